"""The continuous system a sampled one came from: ``rc.d2c(G, method="zoh" | "tustin")``.

* ``"zoh"`` inverts the zero-order-hold equivalent ``[[Phi, Gamma], [0, I]] =
  expm([[A, B], [0, 0]] T)`` (Franklin, Powell & Workman 1998, "Digital Control of Dynamic
  Systems", eq. 4.58) with the principal matrix logarithm: ``[[A, B], [0, 0]] =
  logm([[Phi, Gamma], [0, I]]) / T``; ``C`` and ``D`` are unchanged. A real ``A`` exists for
  the principal branch only when ``Phi`` has no eigenvalue on the closed negative real axis
  (Higham 2008, "Functions of Matrices", thm 1.31): a pole at ``z <= 0`` (a sampled system
  with a pole at the origin -- a pure delay -- or one that rings at the Nyquist rate) has no
  continuous ZOH original and is refused. Poles within ``pi / T`` of the frequency axis come
  back where they were; faster ones alias (a continuous pole at ``s`` and one at ``s + 2 pi j
  k / T`` sample alike: the principal branch gives the one in the Nyquist band).
* ``"tustin"`` inverts the bilinear map ``s = (2/T)(z - 1)/(z + 1)`` exactly:
  ``A = (2/T)(Phi + I)^-1 (Phi - I)``, ``B = (2/T)(Phi + I)^-1 Gamma``, ``C = 2 C_d (Phi +
  I)^-1``, ``D = D_d - C_d (Phi + I)^-1 Gamma`` (the inverse of python-control's / scipy's
  ``c2d(method="tustin")``, FPW sec. 6.3.2); a pole at ``z = -1`` maps to ``s = inf`` and is
  refused.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.linalg

from ..checks import choice
from ..errors import ModelError
from ..lti import as_statespace

__all__ = ["d2c"]

#: relative distance of a pole to the negative real axis (zoh) or to -1 (tustin) that is refused
MAP_TOL = 1e-9


def d2c(G: Any, method: str = "zoh"):
    """The continuous-time system whose sampled equivalent is ``G`` (MATLAB ``d2c``).

    Parameters
    ----------
    G : discrete system
        Anything :func:`robustctl.lti.as_statespace` takes, with a sample time ``dt > 0`` (s).
    method : {"zoh", "tustin"}
        The discretisation to invert (module docstring).

    Returns
    -------
    control.StateSpace
        Continuous, with ``G``'s signal and state names.

    Raises
    ------
    ModelError
        ``G`` continuous or with an unspecified sample time; ``"zoh"`` and a pole on the closed
        negative real axis (no real continuous original); ``"tustin"`` and a pole at ``z = -1``.

    Examples
    --------
    >>> import control, robustctl as rc
    >>> G = control.ss([[-2.0]], [[1.0]], [[3.0]], [[0.5]])
    >>> Gc = rc.d2c(control.c2d(G, 0.1, method="zoh"))
    >>> round(float(Gc.A[0, 0]), 10), round(float(Gc.B[0, 0] * Gc.C[0, 0]), 10)
    (-2.0, 3.0)
    """
    import control

    ss = as_statespace(G, name="G")
    method = choice(method, "method", ("zoh", "tustin"), ModelError)
    dt = ss.dt
    if dt is None or dt is True or not dt:
        raise ModelError(
            f"d2c needs a discrete system with a numeric sample time; G has dt={dt!r}. "
            "A continuous system needs no mapping.")
    T = float(dt)
    A, B, C, D = (np.asarray(x, float) for x in (ss.A, ss.B, ss.C, ss.D))
    n, m = A.shape[0], B.shape[1]
    lam = np.linalg.eigvals(A) if n else np.zeros(0)
    if method == "zoh":
        bad = lam[(lam.real <= MAP_TOL * np.maximum(np.abs(lam), 1.0))
                  & (np.abs(lam.imag) <= MAP_TOL * np.maximum(np.abs(lam), 1.0))]
        if bad.size:
            raise ModelError(
                f"d2c(method='zoh'): G has pole(s) at z = {np.round(bad.real, 12).tolist()} on the "
                "closed negative real axis, which no real continuous system sampled with a zero-order hold "
                "produces (a pole at 0 is a pure delay). Remove the delay states, or map with "
                "method='tustin'.")
        big = np.zeros((n + m, n + m))
        big[:n, :n], big[:n, n:], big[n:, n:] = A, B, np.eye(m)
        L = scipy.linalg.logm(big) / T
        if np.iscomplexobj(L):
            L = np.real_if_close(L, tol=1e6)
            if np.iscomplexobj(L):
                raise ModelError("d2c(method='zoh'): the matrix logarithm is not real; G has no real "
                                 "ZOH original.")
        Ac, Bc, Cc, Dc = L[:n, :n], L[:n, n:], C, D
    else:
        near = np.abs(lam + 1.0) <= MAP_TOL * 10
        if np.any(near):
            raise ModelError(
                "d2c(method='tustin'): G has a pole at z = -1, which the bilinear map sends to s = inf; "
                "no proper continuous system has this Tustin equivalent.")
        Pi = np.linalg.inv(A + np.eye(n))
        Ac = (2.0 / T) * Pi @ (A - np.eye(n))
        Bc = (2.0 / T) * Pi @ B
        Cc = 2.0 * C @ Pi
        Dc = D - C @ Pi @ B
    return control.ss(Ac, Bc, Cc, Dc, inputs=list(ss.input_labels), outputs=list(ss.output_labels),
                      states=list(ss.state_labels))
