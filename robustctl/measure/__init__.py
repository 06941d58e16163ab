"""The measure stage: how frequency-response data are made and how far they can be trusted.

Modules: ``estimate`` (H1 estimation from time records, simulated experiments, combining
experiments), ``impact`` (hammer-test FRFs), ``impact_view`` (what an impact test's H1 makes of
a model: the exponential window's pole shift and the record end, eqs. W1, W2 and T1),
``estimator`` (what the H1 estimator makes of a model: window leakage, held commands, bin
correlation, and the impact view applied) and ``noise`` (the noise model of an
estimate and the chi-square verdicts built on it).
"""

__all__: list[str] = []
