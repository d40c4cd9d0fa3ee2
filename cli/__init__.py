"""The application layer: the command line (``rig``, ``dataset``, ``train``/``generate``/``evaluate``).

Commands parse arguments and call library functions; heavy imports (torch, diffusers)
happen inside the model commands so that ``rig --help`` stays fast.
"""
