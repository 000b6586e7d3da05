"""The workflow's stages as library functions: one module per stage, plain values in (arrays keyed by curve
label, the config's numbers, the dicts of the files a stage reads) and the dict its file holds out.

The workflow's scripts (``workflow/scripts/``) read a rule's inputs, call the stage and write its dict; the
one-call API (:func:`imupipe.api.noise_model`) calls the same stages in the same order on in-memory records,
so the two cannot disagree (tests/test_orchestration_parity.py).

==============================  ==================  ==========================================================
module                          rule                stage function
==============================  ==================  ==========================================================
:mod:`imupipe.stages.identify`  identify            :func:`~imupipe.stages.identify.identification_stage`
:mod:`imupipe.stages.bound`     bound               :func:`~imupipe.stages.bound.bound_stage`
:mod:`imupipe.stages.verify`    verify              :func:`~imupipe.stages.verify.verify_stage`
:mod:`imupipe.stages.contract`  contract            :func:`~imupipe.stages.contract.contract_stage`
:mod:`imupipe.stages.contract`  integrity           :func:`~imupipe.stages.contract.verdict_stage`
:mod:`imupipe.stages.kf`        kf                  :func:`~imupipe.stages.kf.kf_stage`
==============================  ==================  ==========================================================

The modules are imported on use (``from imupipe.stages import identify``): importing the package loads
nothing heavy.
"""

__all__ = ["bound", "contract", "identify", "kf", "verify"]
