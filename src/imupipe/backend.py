"""Which implementation runs a numerical loop: the optional compiled module ``imupipe._kernels`` or NumPy.

Both give the same numbers to rounding (each caller's tests compare them); the compiled loops are only faster.
"""

from __future__ import annotations

__all__ = ["BACKENDS", "choose_backend"]

#: The accepted ``backend`` arguments.
BACKENDS = ("auto", "c", "numpy")


def choose_backend(backend: str, kernels) -> str:
    """'c' or 'numpy' for `backend` ('auto': 'c' when `kernels`, the caller's compiled module, is not None).

    Raises ValueError for an unknown `backend` and RuntimeError for 'c' without the compiled module."""
    if backend not in BACKENDS:
        raise ValueError(f"backend must be 'auto', 'c' or 'numpy', got {backend!r}")
    if backend == "c" and kernels is None:
        raise RuntimeError("the compiled kernel imupipe._kernels is not available (use backend='numpy')")
    if backend == "auto":
        return "c" if kernels is not None else "numpy"
    return backend
