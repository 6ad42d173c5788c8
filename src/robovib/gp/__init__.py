"""Gaussian-process regression of pose-dependent quantities (thesis §3.3, Eq. 6-10, 33-36)."""

from .regressor import BatchedGPRegressor, GPHyperparameters, GPNumericalError, JitterWarning

__all__ = ["BatchedGPRegressor", "GPHyperparameters", "GPNumericalError", "JitterWarning"]
