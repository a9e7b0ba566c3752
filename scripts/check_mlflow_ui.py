"""Open the MLflow UI in a real browser and check that it shows the pipeline's runs and what tells them apart.

Starts `mlflow ui` on 127.0.0.1 over the repository's store and loads two pages
in headless Chromium (Debian's `chromium` package), letting their scripts run:

- the runs table, http://127.0.0.1:PORT/#/experiments/<id>/runs, searched
  for each stage's name as a user would (`searchFilter=attributes.run_name =
  '<stage>'`), which must list that stage's runs: unsearched, its first page
  holds the newest 100 runs, child runs included, and with three worlds
  those are the last stages' alone;
- the compare page of the newest `crossval` run's child runs (one per
  method), #/compare-runs?runs=[...], which must show every child's `method`
  param, as a user comparing methods sees them.

Exit code 0 when both pages show everything, 1 when something is missing, 2
when the store, the experiment or Chromium is missing.

    python scripts/check_mlflow_ui.py [--store mlflow.db] [--expect crossval noise ...] [--children crossval]
"""

from __future__ import annotations

import argparse
import json
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
import urllib.request
from pathlib import Path

from mlflow.tracking import MlflowClient

from taskseq.track.mlflow_runs import EXPERIMENT

STAGES = ("select", "train", "fold_models", "crossval", "noise", "feedback", "recipes", "scenes", "aggregate",
          "report")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--store", type=Path, default=Path("mlflow.db"), help="SQLite store (default mlflow.db)")
    parser.add_argument("--expect", nargs="+", default=list(STAGES), help="run names the runs table must list")
    parser.add_argument("--children", default="crossval",
                        help="stage whose newest run's child runs the compare page must show (default crossval)")
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
    children = child_runs(MlflowClient(tracking_uri=uri), exp.experiment_id, args.children)
    if not children:
        print(f"error: {args.store}: no {args.children!r} run with child runs; run `dvc repro` first", file=sys.stderr)
        return 2
    port = free_port()
    ui = subprocess.Popen([sys.executable, "-m", "mlflow", "ui", "--backend-store-uri", uri, "--host", "127.0.0.1",
                           "--port", str(port)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    base = f"http://127.0.0.1:{port}/#"
    runs_url = f"{base}/experiments/{exp.experiment_id}/runs"
    ids = json.dumps([run.info.run_id for run in children], separators=(",", ":"))
    compare_url = f"{base}/compare-runs?runs={ids}&experiments={json.dumps([exp.experiment_id])}"
    try:
        for _ in range(120):  # the server takes a few seconds to start
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=2)
                break
            except OSError:
                time.sleep(0.5)
        searched = {name: render(browser, f"{runs_url}?" + urllib.parse.urlencode(
            {"searchFilter": f"attributes.run_name = '{name}'"}, quote_via=urllib.parse.quote))
            for name in args.expect}
        compare_page = render(browser, compare_url)
    finally:
        ui.terminate()
        ui.wait(timeout=30)
    missing = [name for name, page in searched.items() if f">{name}<" not in page]
    print(f"{runs_url}, searched by run name: {len(args.expect) - len(missing)} of {len(args.expect)} stages listed"
          + (f"; missing {', '.join(missing)}" if missing else ""))
    methods = sorted({run.data.params.get("method", run.info.run_name) for run in children})
    unshown = [m for m in methods if f">{m}<" not in compare_page]
    if ">method<" not in compare_page:  # the params table's row that tells the runs apart
        unshown.append("the `method` param row")
    print(f"compare page of the {len(children)} child runs of {args.children}: "
          f"{len(methods) - len(unshown)} of {len(methods)} methods shown"
          + (f"; missing {', '.join(unshown)}" if unshown else ""))
    return 1 if missing or unshown else 0


def child_runs(client: MlflowClient, experiment_id: str, parent_name: str) -> list:
    """The child runs of the newest run named `parent_name` that has any."""
    parents = client.search_runs([experiment_id], filter_string=f"attributes.run_name = '{parent_name}'",
                                 order_by=["attributes.start_time DESC"], max_results=20)
    for parent in parents:
        query = f"tags.mlflow.parentRunId = '{parent.info.run_id}'"
        children = client.search_runs([experiment_id], filter_string=query, max_results=200)
        if children:
            return children
    return []


def render(browser: str, url: str) -> str:
    """The page's DOM after its scripts ran, from headless Chromium with a throw-away profile."""
    with tempfile.TemporaryDirectory() as profile:
        return subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                               "--no-first-run", "--disable-background-networking", "--disable-component-update",
                               "--disable-sync", f"--user-data-dir={profile}", "--virtual-time-budget=20000",
                               "--window-size=1600,5000", "--dump-dom", url],
                              capture_output=True, text=True, timeout=180).stdout


if __name__ == "__main__":
    sys.exit(main())
