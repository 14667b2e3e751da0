"""Physics of shape-engineered pneumatic microtube actuators.

Pure models, no images or files beyond sample TOML: the eccentric-annulus cross
section, the multi-segment Euler–Bernoulli beam model and the line-segment model
of the seed paper (§2.3–2.4), for any number of sections. Lengths are in µm,
pressures and moduli in MPa, angles in radians inside and degrees at the edges.
"""

from .euler_bernoulli import eb_bend_angle, eb_curvatures, eb_shape, eb_shape_trapezoid
from .line_segment import (
    LSParams,
    ls_bend_angle,
    ls_limit_shape,
    ls_shape,
    ls_shape_cumsum,
    ls_tilts,
    segment_counts,
)
from .samples import (
    PAPER_SAMPLES,
    PAPER_TABLE2,
    Sample,
    Section,
    get_sample,
    load_sample_toml,
    sample_from_dict,
)
from .section import CrossSection, cross_section
from .shape import Shape

__all__ = [
    "CrossSection", "LSParams", "PAPER_SAMPLES", "PAPER_TABLE2", "Sample", "Section",
    "Shape", "cross_section", "eb_bend_angle", "eb_curvatures", "eb_shape",
    "eb_shape_trapezoid", "get_sample", "load_sample_toml", "ls_bend_angle", "ls_limit_shape",
    "ls_shape", "ls_shape_cumsum", "ls_tilts", "sample_from_dict", "segment_counts",
]
