"""The application layer: the command line (``rig``, ``dataset``, ``train``/``generate``/``evaluate``).

Commands parse arguments and call library functions; heavy imports (torch, diffusers)
happen inside the model commands so that ``rig --help`` stays fast. The first instruction of
a moving rig command holds SIGINT, SIGTERM and SIGHUP until its motion session can act on them
(rig/early_signals.py): a signal while Python imports or the rig opens still lifts z. numpy's
matrix products run on the calling thread (common/blas_threads.py). A Ctrl-C while this file runs
ends the command as one in cli/entry.py does: one line, then SIGINT.
"""

import sys as _sys

try:
    from common.blas_threads import one_blas_thread as _one_blas_thread
    from rig.early_signals import hold_if_moving as _hold_if_moving

    _hold_if_moving(_sys.argv)
    _one_blas_thread()  # before numpy loads: its BLAS thread pool has hung with concurrent callers
except KeyboardInterrupt:  # a Ctrl-C before cli/entry.py's first line: its one line, its end by SIGINT
    from cli.entry import die_by_sigint

    die_by_sigint()
