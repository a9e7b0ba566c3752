"""requirements.lock pins everything the install brings, so a fresh machine gets the versions behind dvc.lock."""

import re
from importlib.metadata import PackageNotFoundError, distribution
from pathlib import Path

from packaging.requirements import Requirement

LOCK = Path(__file__).resolve().parents[1] / "requirements.lock"


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _locked() -> dict[str, str]:
    pins = {}
    for n, line in enumerate(LOCK.read_text().splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        name, sep, version = line.partition("==")
        assert sep and version, f"{LOCK.name}:{n}: expected 'name==version', got {line!r}"
        pins[_norm(name)] = version
    return pins


def _needed(extras: tuple[str, ...] = ("dev", "dask")) -> set[str]:
    """Every distribution taskseq needs with these extras, followed through the installed metadata."""
    seen, todo = set(), [(Requirement(f"taskseq[{','.join(extras)}]"), ())]
    while todo:
        req, parent_extras = todo.pop()
        name = _norm(req.name)
        if req.marker is not None and not any(req.marker.evaluate({"extra": e}) for e in (*parent_extras, "")):
            continue
        if name in seen:
            continue
        seen.add(name)
        try:
            dist = distribution(req.name)
        except PackageNotFoundError:
            continue  # not installed here (another platform's dependency): nothing to follow
        todo += [(Requirement(r), tuple(req.extras)) for r in dist.requires or []]
    return seen - {"taskseq"}


def test_every_needed_package_is_pinned():
    missing = sorted(_needed() - set(_locked()) - {"setuptools", "pip"})
    assert not missing, f"missing from {LOCK.name} (re-lock as docs/getting-started.md says): {missing}"


def test_the_key_packages_are_pinned_to_exact_versions():
    pins = _locked()
    for name in ("numpy", "pyarrow", "numba", "pandas", "scikit-learn", "dvc", "mlflow"):
        assert re.fullmatch(r"\d+(\.\d+)*\S*", pins[name]), name


def test_dvc_reads_the_pipelines_files_with_the_c_parser_and_the_same_values():
    # DVC parses dvc.lock several times for every stage it runs: 0.2 s each with the C parser, 1 s without
    from ruamel.yaml import YAML, main

    assert main.CParser is not None, "ruamel.yaml.clib is not installed (pyproject.toml lists it)"
    root = LOCK.parent
    parts = [str(p.relative_to(root)) for p in sorted(root.glob("pipelines/*/dvc.*"))]
    assert parts  # the pipeline's parts, each with its dvc.yaml and dvc.lock
    for name in ("dvc.yaml", "dvc.lock", "params.yaml", "veil/dvc.yaml", "veil/params.yaml", *parts):
        text = (root / name).read_text()
        assert YAML(typ="safe").load(text) == YAML(typ="safe", pure=True).load(text), name
