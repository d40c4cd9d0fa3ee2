"""The application layer: the command line (``rig``, ``dataset``, ``train``/``generate``/``evaluate``).

Commands parse arguments and call library functions; heavy imports (torch, diffusers)
happen inside the model commands so that ``rig --help`` stays fast. The first instruction of
a moving rig command holds SIGINT, SIGTERM and SIGHUP until its motion session can act on them
(rig/early_signals.py): a signal while Python imports or the rig opens still lifts z. numpy's
matrix products run on the calling thread (common/blas_threads.py).
"""

import sys as _sys

from rig.early_signals import EARLY as _EARLY
from rig.early_signals import hold_if_moving as _hold_if_moving

_hold_if_moving(_sys.argv)
if not _EARLY.active:  # any other console script: a Ctrl-C during an import is held until it ends
    from cli.entry import hold_ctrl_c_in_imports as _hold_ctrl_c_in_imports

    _hold_ctrl_c_in_imports(_sys.argv)

from common.blas_threads import one_blas_thread as _one_blas_thread  # noqa: E402 (after the holds)

_one_blas_thread()  # before numpy loads: its BLAS thread pool has hung with concurrent callers
