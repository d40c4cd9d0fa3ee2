"""``rig console``: a local web page for the rig and its run files (docs/console.md).

- ``worker``: the one thread that owns the rig (blocking devices); commands in, snapshots out;
- ``hub``: the browsers connected over WebSockets, who holds control, latest-wins delivery;
- ``runs``: the run browser's reads of HDF5 run files (also while they are being written);
- ``server``: the Starlette app, its routes and the access token; ``serve`` runs it with uvicorn.

The page and its vendored chart library (uPlot, MIT) are in ``static/``: nothing is fetched
from the internet and nothing is built at install time.
"""
