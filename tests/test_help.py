"""Every command's options explain themselves: a help text for each, and a stated default
where the option has no fixed one to show."""

import pytest
import typer

from cli.dataset_app import app as dataset_app
from cli.model_app import app as train_app
from cli.model_app import compare_app, evaluate_app, generate_app
from cli.rig_app import app as rig_app

APPS = {
    "rig": rig_app,
    "dataset": dataset_app,
    "train": train_app,
    "generate": generate_app,
    "evaluate": evaluate_app,
    "compare": compare_app,
}


def _commands(name, group):
    if hasattr(group, "commands"):  # a group (typer vendors its own click classes)
        for sub_name, sub in group.commands.items():
            yield from _commands(f"{name} {sub_name}", sub)
    else:
        yield name, group


def _all_options():
    for name, app in APPS.items():
        for cmd_name, cmd in _commands(name, typer.main.get_command(app)):
            for p in cmd.params:
                if p.param_type_name == "option" and p.name != "help":
                    yield cmd_name, p


@pytest.mark.parametrize("cmd_name,option", list(_all_options()), ids=lambda v: getattr(v, "name", v))
def test_every_option_has_help_and_a_default_or_says_it_is_required(cmd_name, option):
    text = (option.help or "").strip()
    assert len(text) >= 10, f"{cmd_name} --{option.name}: no help"
    if option.required or option.is_flag or option.default is not None:
        return  # required, a switch, or a default the help screen shows
    assert "default" in text.lower(), f"{cmd_name} --{option.name}: no default is shown and the help does not state one"


def test_no_help_text_loses_a_bracketed_word_to_markup():
    """`train --help` read "A model TOML: preset,  and  tables": rich took [model] and [train] for markup
    (issue 37). Every bracketed word of every help text is shown as written."""
    import re

    from rich.markup import render

    lost = []
    texts = [(cmd_name, option.name, option.help) for cmd_name, option in _all_options()]
    for name, app in APPS.items():
        texts += [
            (cmd_name, "(its description)", cmd.help) for cmd_name, cmd in _commands(name, typer.main.get_command(app))
        ]
    for cmd_name, option_name, help_text in texts:
        text = help_text or ""
        shown = render(text).plain
        for word in re.findall(r"\\?\[[A-Za-z_][\w. -]*\]", text):
            if word.lstrip("\\") not in shown:
                lost.append(f"{cmd_name} --{option_name}: {word}")
    assert not lost, lost
