"""Wording several commands share (common/wording.py)."""

from common.wording import status_text


def test_a_status_and_its_reason_never_say_the_status_twice():
    reason = "interrupted (SIGINT); resume with --resume"
    assert status_text("interrupted", reason) == "interrupted (SIGINT; resume with --resume)"
    assert status_text("interrupted", "interrupted (Ctrl-C)") == "interrupted (Ctrl-C)"
    assert status_text("aborted", "ValueError: bad reply from z") == "aborted (ValueError: bad reply from z)"
    assert status_text("complete", "") == "complete" and status_text("complete", None) == "complete"
    assert status_text("interrupted", "interrupted") == "interrupted"


def test_the_reason_alone_drops_the_status_word():
    from common.wording import reason_only

    assert reason_only("interrupted", "interrupted (SIGINT); resume with --resume") == "SIGINT; resume with --resume"
    assert reason_only("aborted", "disk full") == "disk full" and reason_only("aborted", None) == ""
