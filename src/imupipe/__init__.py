"""imupipe: integrity-grade stochastic IMU error models from static recordings and a spec sheet.

Public API (imported lazily so that workflow jobs pay only for what they use)::

    imupipe.allan_variance(x, rate, taus="octave", overlapping=True)   # xarray.Dataset
    imupipe.psd(x, rate, ...)                                           # xarray.Dataset, two-sided
    imupipe.NoiseModel(white=N, gauss_markov=[(sigma, T)], random_walk=K, ...)
    imupipe.units                                                       # spec-sheet units <-> SI
    imupipe.noise_model(curves, record_rate_hz, sensor, spec)           # identification + bound + KF, one call

Command line: ``imupipe run|allan|check`` (:mod:`imupipe.cli`), also ``python -m imupipe``.
"""

from importlib import import_module

__version__ = "0.2.0"

_LAZY = {
    "allan_variance": ("imupipe.allan", "allan_variance"),
    "psd": ("imupipe.spectra", "psd"),
    "decimate": ("imupipe.spectra", "decimate"),
    "NoiseModel": ("imupipe.models", "NoiseModel"),
    "simulate": ("imupipe.simulate", "simulate"),
    "units": ("imupipe.units", None),
    "noise_model": ("imupipe.api", "noise_model"),
    "NoiseModelResult": ("imupipe.api", "NoiseModelResult"),
    "render_summary": ("imupipe.summary", "render_summary"),
    "kalibr_imu": ("imupipe.kalibr", "kalibr_imu"),
}

__all__ = sorted(_LAZY)


def __getattr__(name: str):
    try:
        module_name, attribute = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'imupipe' has no attribute {name!r}") from None
    module = import_module(module_name)
    value = module if attribute is None else getattr(module, attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
