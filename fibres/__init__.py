"""Muscle fibre decomposition (Kohout et al., GRAPP 2012): pure geometry on arrays.

Never imports ``motion`` or ``analysis``.
"""
from .bundle import FibreBundle
from .decompose import DEFAULT_SLICING, SLICINGS, decompose, make_plan
from .errors import InputError, MissingDependencyError
from .slicing.mvc import mean_value_coordinates
from .plan import DecompositionPlan
from .slicing.harmonic import HarmonicPlan
from .finishing.quality import FibreQuality, FibreQualityWarning
from .template.sampling import sobol_rs
from .mesh.surface import Surface, as_surface
from .template.templates import TEMPLATES, get_template

__all__ = ["InputError", "MissingDependencyError", "Surface", "as_surface", "sobol_rs", "get_template", "TEMPLATES",
           "decompose", "FibreBundle", "DecompositionPlan", "make_plan", "mean_value_coordinates",
           "HarmonicPlan", "FibreQuality", "FibreQualityWarning", "SLICINGS", "DEFAULT_SLICING"]
