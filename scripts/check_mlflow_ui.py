"""Open the MLflow runs page in a real browser and check that the pipeline's runs are listed.

Starts `mlflow ui` on 127.0.0.1 over the repository's store, loads
http://127.0.0.1:PORT/#/experiments/<id>/runs in headless Chromium (Debian's
`chromium` package), lets the page's scripts run, and looks for the stage runs'
names in the page it rendered. Exit code 0 when all are there, 1 when some are
missing, 2 when the store, the experiment or Chromium is missing.

    python scripts/check_mlflow_ui.py [--store mlflow.db] [--expect crossval noise ...]
"""

from __future__ import annotations

import argparse
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

from mlflow.tracking import MlflowClient

from pipeline.track.mlflow_runs import EXPERIMENT

STAGES = ("select", "train", "folds", "crossval", "noise", "feedback", "recipes", "aggregate", "report")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--store", type=Path, default=Path("mlflow.db"), help="SQLite store (default mlflow.db)")
    parser.add_argument("--expect", nargs="+", default=list(STAGES), help="run names the page must list")
    args = parser.parse_args()
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        print("error: no chromium on PATH (Debian: apt-get install chromium)", file=sys.stderr)
        return 2
    if not args.store.exists():
        print(f"error: {args.store}: no MLflow store; run `dvc repro` first", file=sys.stderr)
        return 2
    uri = f"sqlite:///{args.store.resolve()}"
    exp = MlflowClient(tracking_uri=uri).get_experiment_by_name(EXPERIMENT)
    if exp is None:
        print(f"error: {args.store}: no experiment {EXPERIMENT!r}", file=sys.stderr)
        return 2
    port = free_port()
    ui = subprocess.Popen([sys.executable, "-m", "mlflow", "ui", "--backend-store-uri", uri, "--host", "127.0.0.1",
                           "--port", str(port)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        for _ in range(120):  # the server takes a few seconds to start
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=2)
                break
            except OSError:
                time.sleep(0.5)
        url = f"http://127.0.0.1:{port}/#/experiments/{exp.experiment_id}/runs"
        with tempfile.TemporaryDirectory() as profile:
            page = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                                   "--no-first-run", "--disable-background-networking", "--disable-component-update",
                                   "--disable-sync", f"--user-data-dir={profile}", "--virtual-time-budget=20000",
                                   "--window-size=1600,5000", "--dump-dom", url],
                                  capture_output=True, text=True, timeout=180).stdout
    finally:
        ui.terminate()
        ui.wait(timeout=30)
    missing = [name for name in args.expect if f">{name}<" not in page]
    print(f"{url}: {len(args.expect) - len(missing)} of {len(args.expect)} runs listed"
          + (f"; missing {', '.join(missing)}" if missing else ""))
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
