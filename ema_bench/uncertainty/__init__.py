"""How sure is a fit: intervals and identifiability of the fitted fault parameters.

* :mod:`~ema_bench.uncertainty.noise` -- the sensors' known noise per signal and the noise
  level estimated from a fit's residuals;
* :mod:`~ema_bench.uncertainty.local` -- the Jacobian of the outputs, the Laplace
  (Gauss-Newton sandwich) covariance and its intervals;
* :mod:`~ema_bench.uncertainty.profile` -- profile-likelihood intervals (the others
  re-optimised along a grid, warm started, with a budget);
* :mod:`~ema_bench.uncertainty.bootstrap` -- parametric bootstrap (refits on resampled noise);
* :mod:`~ema_bench.uncertainty.model_form` -- the allowance for model-form error, calibrated on
  the twin/reference pair;
* :mod:`~ema_bench.uncertainty.identifiability` -- correlations, singular values, weakest
  directions in physical units;
* :mod:`~ema_bench.uncertainty.methods` -- one entry point, :func:`intervals`, and a registry
  of methods.
"""

from .methods import METHODS, Intervals, intervals  # noqa: F401
