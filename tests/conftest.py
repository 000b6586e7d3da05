"""Shared fixtures: the validation data folder beside the project (``../shared/data``)."""

from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = PROJECT_ROOT.parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Path of ``../shared/data``; skips the test with a reason where the folder is absent (a user's clone)."""
    if not SHARED_DATA.is_dir():
        pytest.skip(
            f"validation data not found at {SHARED_DATA} (third-party reference data, kept outside the project; "
            "CI provides it)"
        )
    return SHARED_DATA


@pytest.fixture
def rng():
    import numpy as np

    return np.random.default_rng(20211101)


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory):
    """A complete run of the tiny configuration (tests/configs/tiny.yaml) in a copy of the checkout (its own
    spec sheets), run from the copy's folder: (folder, config file). Shared by every workflow test module, and
    under pytest-xdist (``make test``) by every worker: the first worker to ask builds it in the session's common
    folder under a file lock (pytest-xdist's documented way to build a session fixture once), the others wait for
    it. Tests only read it and dry-run it; a test that writes into a run (edits its spec sheet, removes an output,
    writes a report) takes :func:`tiny_copy`."""
    import os

    from filelock import FileLock

    if os.environ.get("PYTEST_XDIST_WORKER") is None:
        return _build_tiny_run(tmp_path_factory.mktemp("tiny"))
    root = tmp_path_factory.getbasetemp().parent / "tiny_run"
    with FileLock(f"{root}.lock"):
        done = root / "built"
        if not done.is_file():
            _build_tiny_run(root)
            done.touch()
    return root / "checkout", root / "checkout" / "tiny.yaml"


def _build_tiny_run(root):
    import shutil

    pytest.importorskip("snakemake", reason="the workflow tests need snakemake (pip install -e '.[test]')")
    from workflow_helpers import TINY, copy_checkout, snakemake

    work = copy_checkout(root / "checkout")
    config = work / "tiny.yaml"
    shutil.copy2(TINY, config)
    snakemake(work, config=config, snakefile=work / "Snakefile")
    return work, config


@pytest.fixture
def tiny_copy(tiny_run, tmp_path):
    """A private copy of :func:`tiny_run` (modification times kept, so it is as up to date as the run):
    (folder, config file), for a test that writes into the run."""
    from workflow_helpers import copy_run

    work, config = tiny_run
    copy = copy_run(work, tmp_path / "checkout")
    return copy, copy / config.name


@pytest.fixture(scope="session")
def half_spec_accel_case():
    """An accel truth (white 1e-4 m/s^2/sqrt(Hz) + GM 5e-5 m/s^2 at 200 s), two 3 h records of it at 5 Hz (seed 31)
    and a spec sheet of half its values: the case of the auto bound's end-to-end tests (truth, records, spec)."""
    import numpy as np

    from imupipe.models import NoiseModel
    from imupipe.simulate import simulate
    from imupipe.specsheet import parse_spec

    truth = NoiseModel(white=1e-4, gauss_markov=((5e-5, 200.0),))
    X = simulate(truth, 3 * 3600 * 5, 5.0, rng=np.random.default_rng(31), n_records=2)
    spec = parse_spec({"name": "half", "accel": {
        "white": {"value": 5e-5, "unit": "m/s^2/sqrt(Hz)"},
        "gauss_markov": [{"sigma": {"value": 2.5e-5, "unit": "m/s^2"}, "T": {"value": 200.0, "unit": "s"}}]}})
    return truth, {"a/x": X[0], "b/x": X[1]}, spec
