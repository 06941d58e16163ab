"""The measure stage: how frequency-response data are made and how far they can be trusted.

Modules: ``estimate`` (H1 estimation from time records, simulated experiments, combining
experiments), ``impact`` (hammer-test FRFs), ``estimator`` (what the H1 estimator makes of a
model: window leakage, held commands, bin correlation) and ``noise`` (the noise model of an
estimate and the chi-square verdicts built on it).
"""

__all__: list[str] = []
