"""Fast frequency responses, conversions to and from python-control, log errors.

All FRF arrays have the shape (n_freq, n_out, n_in); surface frequencies are in Hz.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import DataError, ModelError
from .frd import FrequencyData

__all__ = ["freqresp"]


def _as_statespace(sys: Any):
    import control

    try:
        ss = control.ss(sys)
    except Exception as exc:  # python-control raises several types
        raise ModelError(f"cannot convert {type(sys).__name__} to a state space: {exc}") from exc
    return ss


def freqresp(sys: Any, f_hz: Any) -> FrequencyData:
    """Frequency response of ``sys`` at ``f_hz`` (Hz) as FrequencyData."""
    ss = _as_statespace(sys)
    f = np.asarray(f_hz, dtype=float).reshape(-1)
    if f.size == 0 or not np.all(np.isfinite(f)):
        raise DataError("f_hz must be a non-empty array of finite frequencies in Hz.")
    A, B, C, D = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    n = A.shape[0]
    out = np.empty((f.size, C.shape[0], B.shape[1]), dtype=complex)
    eye = np.eye(n)
    for k, fk in enumerate(f):
        s = 2j * np.pi * fk
        out[k] = D + (C @ np.linalg.solve(s * eye - A, B) if n else 0.0)
    return FrequencyData(f, out, inputs=ss.input_labels, outputs=ss.output_labels)


def as_statespace(sys: Any):
    """``sys`` as a ``control.StateSpace`` with named signals.

    Accepts a ``control.StateSpace``, anything ``control.ss`` converts (transfer
    functions, scalars ...) and a robustctl ``PhysicalModel`` (via ``.statespace()``).
    """
    import control

    if isinstance(sys, control.StateSpace):
        return sys
    if hasattr(sys, "statespace") and callable(sys.statespace):
        return _as_statespace(sys.statespace())
    return _as_statespace(sys)
