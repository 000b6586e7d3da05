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
    spec sheets), run from the copy's folder: (folder, config file). Shared by every workflow test module."""
    import shutil

    pytest.importorskip("snakemake", reason="the workflow tests need snakemake (pip install -e '.[test]')")
    from workflow_helpers import TINY, copy_checkout, snakemake

    work = copy_checkout(tmp_path_factory.mktemp("tiny") / "checkout")
    config = work / "tiny.yaml"
    shutil.copy2(TINY, config)
    snakemake(work, config=config, snakefile=work / "Snakefile")
    return work, config
