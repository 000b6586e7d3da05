r"""Per-axis bounding models, for the KF export when the axes of a sensor type differ.

When the pooling test of the identification (:mod:`imupipe.identify`) rejects one model for every curve of
a sensor type, the global bound still covers every curve (it is the bound of the worst axis at each
frequency), but a navigation filter that runs one error model per axis can use a tighter model on the
quieter axes. :func:`bound_by_axis` solves, for each axis, the same problem as the global bound
(:func:`imupipe.bound.bound_psd`: same LP, mode, GM count, kept components, all-frequency rows, spec-sheet
floor and line policy) over that axis's curves of every dataset, with that axis's identified upper
envelope in place of the pooled one. Each per-axis model then bounds its own curves, the spec sheet and
its own envelope at every frequency; it is NOT a bound of the other axes' curves (docs/method.md, section
"Per-axis models").

Curve labels are ``"{dataset}/{axis}"`` (the workflow's stacked files); the axis is the part after the
last ``/``.
"""

from __future__ import annotations


def axis_of(label: str) -> str:
    """The axis of a ``"{dataset}/{axis}"`` curve label (the text after the last ``/``).

    Raises
    ------
    ValueError
        A label without ``/``.
    """
    label = str(label)
    if "/" not in label:
        raise ValueError(f"curve label {label!r}: expected 'dataset/axis'")
    return label.rsplit("/", 1)[1]


def curves_by_axis(labels) -> dict:
    """``{axis: [label, ...]}`` in the order of `labels` (``"{dataset}/{axis}"`` strings)."""
    out: dict = {}
    for lab in labels:
        out.setdefault(axis_of(lab), []).append(str(lab))
    return out


def bound_by_axis(frequency, curves: dict, spec_model=None, upper_models: dict | None = None, edf: dict | None = None,
                  line_kwargs: dict | None = None, **kwargs) -> dict:
    r"""One :func:`imupipe.bound.bound_psd` per axis, over that axis's curves of every dataset.

    Parameters
    ----------
    frequency : array_like
        Frequency grid of the sample PSDs, Hz (shared by every curve).
    curves : dict
        ``"{dataset}/{axis}"`` -> two-sided sample PSD, u^2/Hz.
    spec_model : imupipe.models.NoiseModel, optional
        Spec-sheet model (SI): every per-axis bound dominates it at every frequency, as the global one.
    upper_models : dict, optional
        Axis -> that axis's identified upper confidence envelope (SI :class:`imupipe.models.NoiseModel`,
        the all-frequency rows). An axis missing here gets no envelope rows (None).
    edf : dict, optional
        Label -> degrees of freedom of the curve's ordinates (scalar or per frequency).
    line_kwargs : dict, optional
        Axis -> the ``exclude``/``narrowband`` keyword arguments of that axis's line policy
        (:meth:`imupipe.lines.LinePolicy.bound_kwargs`).
    **kwargs
        Every other :func:`imupipe.bound.bound_psd` argument (dt, mode, n_gm, keep, span_s, ...), the same
        for every axis.

    Returns
    -------
    dict
        Axis -> (labels of its curves, :class:`imupipe.bound.BoundResult`), axes in first-seen order.
    """
    import numpy as np

    from imupipe.bound.engine import bound_psd

    if not curves:
        raise ValueError("bound_by_axis: no curves")
    upper_models = upper_models or {}
    line_kwargs = line_kwargs or {}
    out = {}
    for ax, labels in curves_by_axis(list(curves)).items():
        e = None
        if edf is not None:
            n = np.asarray(frequency).shape[0]
            e = np.array([np.broadcast_to(np.asarray(edf[lab], dtype=np.float64), (n,)) for lab in labels])
        res = bound_psd(frequency, {lab: curves[lab] for lab in labels}, spec_model, edf=e,
                        upper_model=upper_models.get(ax), **{**kwargs, **(line_kwargs.get(ax) or {})})
        out[ax] = (labels, res)
    return out
