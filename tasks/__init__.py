"""The task library (``wbc.tasks``): every task turns itself into affine terms of a stack."""

from .linear import Bounds, LinearConstraint, LinearTask

__all__ = ["Bounds", "LinearConstraint", "LinearTask"]
