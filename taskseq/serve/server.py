"""Run the application until Ctrl-C or SIGTERM, then let the record being written finish.

Werkzeug's threaded server answers each request in its own thread. A
stopping signal reaches the main thread (`taskseq.runtime.stopping` turns SIGTERM
into `KeyboardInterrupt` as for every command), which ends `serve_forever`.
The writer is then closed before the process exits: that waits for an
append under way, so every demonstration whose page said "saved" is whole
on disk, and no other is started.
"""

from __future__ import annotations

import sys
from pathlib import Path

from werkzeug.serving import make_server

from .app import create_app


def serve(host: str, port: int, data: Path, model: Path, top_k: int) -> int:
    app = create_app(data, model, top_k)
    served = app.extensions["taskseq"]
    server = make_server(host, port, app, threaded=True)
    print(f"taskseq serve: open http://{host}:{server.port}/ (records go to {served.people}); "
          "Ctrl-C stops it", flush=True)
    try:
        server.serve_forever()  # returns on Ctrl-C or SIGTERM (Werkzeug ends it on KeyboardInterrupt)
    finally:
        served.writer.close()
        server.server_close()
    print("taskseq serve: stopped; every demonstration it saved is whole on disk", file=sys.stderr)
    return 0
