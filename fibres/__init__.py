"""Muscle fibre decomposition (Kohout et al., GRAPP 2012): pure geometry on arrays.

Never imports ``motion`` or ``analysis``.
"""
from .errors import InputError, MissingDependencyError
from .sampling import sobol_rs
from .surface import Surface, as_surface
from .templates import TEMPLATES, get_template

__all__ = ["InputError", "MissingDependencyError", "Surface", "as_surface", "sobol_rs", "get_template", "TEMPLATES"]
