"""The workflow's stages as library functions: one module per stage, plain values in (arrays keyed by curve
label, the config's numbers, the dicts of the files a stage reads) and the dict its file holds out.

The workflow's scripts (``workflow/scripts/``) read a rule's inputs, call the stage and write its dict; the
one-call API (:func:`imupipe.api.noise_model`) calls the same stages in the same order on in-memory records,
so the two cannot disagree (tests/test_orchestration_parity.py).

Rule -> stage function:

- ``simulate`` -> :func:`imupipe.stages.simulate.simulate_stage`
- ``ingest`` (and ``ingest_<channels>``) -> :func:`imupipe.stages.ingest.ingest_stage`
- ``outliers`` -> :func:`imupipe.stages.outliers.outliers_stage`
- ``stationarity`` -> :func:`imupipe.stages.stationarity.stationarity_stage`; ``stationarity_summary`` ->
  :func:`imupipe.stages.stationarity.summary_stage` with :func:`~imupipe.stages.stationarity.paper_tests`
- ``identify`` -> :func:`imupipe.stages.identify.identification_stage`
- ``bound_axis`` -> :func:`imupipe.stages.bound.axis_bound_stage`
- ``bound`` -> :func:`imupipe.stages.bound.bound_stage`
- ``verify`` -> :func:`imupipe.stages.verify.verify_stage`
- ``contract`` -> :func:`imupipe.stages.contract.contract_stage`; ``integrity`` ->
  :func:`imupipe.stages.contract.verdict_stage`
- ``kf`` -> :func:`imupipe.stages.kf.kf_stage`
- ``kalibr`` -> :func:`imupipe.stages.kalibr.kalibr_stage`
- ``figures`` -> :func:`imupipe.stages.figures.figures_stage`
- ``tables`` -> :func:`imupipe.stages.tables.tables_stage`
- ``summary`` -> :func:`imupipe.stages.summary.summary_stage`

The modules are imported on use (``from imupipe.stages import identify``): importing the package loads
nothing heavy.
"""

__all__ = ["bound", "contract", "figures", "identify", "ingest", "kalibr", "kf", "outliers", "simulate", "stationarity",
           "summary", "tables", "verify"]
