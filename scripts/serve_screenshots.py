"""The screenshots of docs/serve.md (`docs/img/serve_demonstrate.png`, `docs/img/serve_assist.png`), from the app.

    python scripts/serve_screenshots.py [--model models/mrf.npz] [--output docs/img]

Starts `taskseq serve`'s app on a free port of 127.0.0.1 with a data folder of its own (a temporary one, holding
only `environments/workshop.json`, laid out from `docs/examples/workshop.yaml` as docs/teach.md does), and drives
Debian's headless Chromium with Playwright, as `tests/test_serve_browser.py` does, 1200 px wide:

- `serve_demonstrate.png`: the demonstrate page of `stir(broth)` in the workshop, participant `walkthrough`, after
  `move_close(soup_pot)`, `grasp(soup_pot)`, `move_close(paint_stick)`, the steps docs/teach.md demonstrates, each
  chosen by clicking its object in the picture, and with the next step being chosen the same way: the
  `place_above` row highlighted and the workbench clicked (outlined, in the row's list, the line above the
  picture saying what to do next);
- `serve_assist.png`: the assist page at the first step of `pour(oil)` in the workshop, with the planner of
  `--model` (the `train` stage's `models/mrf.npz`, which `dvc repro train` writes).

Nothing is recorded anywhere but in the temporary folder, removed at the end. The pictures depend on the model
file, the app and Chromium's fonts, not on the time or on any earlier run.
"""

from __future__ import annotations

import argparse
import logging
import sys
import tempfile
import threading
from pathlib import Path

from playwright.sync_api import sync_playwright
from werkzeug.serving import make_server

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taskseq.serve.app import create_app  # noqa: E402
from taskseq.serve.layout import write_environment  # noqa: E402

CHROMIUM = Path("/usr/bin/chromium")
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--no-first-run", "--hide-scrollbars"]
VIEWPORT = {"width": 1200, "height": 900}
DEMONSTRATED = [("move_close", "soup_pot"), ("grasp", "soup_pot"), ("move_close", "paint_stick")]
CLICKED = ("place_above", "workbench")  # chosen in the picture, not taken


def click_object(page, primitive: str, obj: str) -> None:
    """Fill the row of `primitive` as a person does: click the row, then the object's shape in the top view."""
    page.click(f"tr:has(#step-{primitive}) td.primitive")
    page.locator(f"#scene g[data-object='{obj}'] > rect").click()
    chosen = page.locator(f"#step-{primitive} select").last.input_value()
    if chosen != obj:
        raise RuntimeError(f"clicking {obj} for {primitive} chose {chosen!r}: {page.inner_text('#pick-message')}")


def submit(page, button: str) -> None:
    """Click a form's button and wait for the page it leads to."""
    with page.expect_navigation():
        page.click(button)


def start_task(page, url: str, task: str, arg1: str, mode: str, participant: str = "") -> None:
    """The first page's server file `workshop.json`, then the task, as a person clicks."""
    page.goto(url + "/")
    page.select_option("#named-form select[name=name]", "workshop.json")
    submit(page, "#named-form button")
    page.select_option("#task-form select[name=task]", task)
    page.select_option("#task-form select[name=arg1]", arg1)
    page.fill("#task-form input[name=participant]", participant)
    submit(page, f"#task-form button[value={mode}]")


def screenshots(model: Path, output: Path, chromium: Path = CHROMIUM) -> list[Path]:
    output.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="taskseq-screenshots-") as tmp:
        data = Path(tmp) / "data"
        logging.getLogger("werkzeug").setLevel(logging.WARNING)  # no line per request
        write_environment(ROOT / "docs" / "examples" / "workshop.yaml", data / "environments" / "workshop.json")
        srv = make_server("127.0.0.1", 0, create_app(data, model), threaded=True)
        thread = threading.Thread(target=srv.serve_forever)
        thread.start()
        url = f"http://127.0.0.1:{srv.port}"
        written = []
        try:
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=str(chromium), args=ARGS)
                page = browser.new_context(viewport=VIEWPORT).new_page()
                start_task(page, url, "stir", "broth", "demonstrate", participant="walkthrough")
                for primitive, obj in DEMONSTRATED:
                    click_object(page, primitive, obj)
                    submit(page, f"#step-{primitive} button")
                    if page.locator("#message").count():
                        raise RuntimeError(f"{primitive}({obj}) was refused: {page.inner_text('#message')}")
                click_object(page, *CLICKED)
                written.append(output / "serve_demonstrate.png")
                page.screenshot(path=str(written[-1]), full_page=True)

                page = browser.new_context(viewport=VIEWPORT).new_page()
                start_task(page, url, "pour", "oil", "assist")
                if page.locator("#proposals").count() == 0:
                    raise RuntimeError(f"the assist page shows no proposals (model {model}): "
                                       + page.inner_text("main" if page.locator("main").count() else "body")[:300])
                written.append(output / "serve_assist.png")
                page.screenshot(path=str(written[-1]), full_page=True)
                browser.close()
        finally:
            srv.shutdown()
            thread.join()
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", type=Path, default=ROOT / "models" / "mrf.npz",
                        help="the planner of the assist page (default: models/mrf.npz, from `dvc repro train`)")
    parser.add_argument("--output", type=Path, default=ROOT / "docs" / "img", help="folder of the PNG files")
    parser.add_argument("--chromium", type=Path, default=CHROMIUM, help="the Chromium executable")
    args = parser.parse_args(argv)
    if not args.model.is_file():
        parser.error(f"{args.model}: no model file; `dvc repro train` writes models/mrf.npz")
    for path in screenshots(args.model, args.output, args.chromium):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
