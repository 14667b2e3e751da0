"""How a tube, its pipette and the background look under the microscope.

A look is a few numbers describing the optics, not a picture: the renderer
turns them into cross-section profiles. Transmitted-light looks attenuate the
illumination (layers multiply where the tube crosses itself); the fluorescent
look emits light in proportion to the PDMS path length (layers add); the
relief look (differential interference contrast) shows the slope of that path
length along a shear direction: the tube lit on one flank, shaded on the other.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np


@dataclass(frozen=True)
class Look:
    """Optical settings of a rendered scene.

    Parameters
    ----------
    name : str
    mode : {"transmit", "emit", "relief"}
        ``transmit``: image = illumination · Π transmissions. ``emit``: image =
        dark background + Σ emissions (fluorescence). ``relief``: image =
        background · (1 + slope along the shear of Σ path lengths · absorption_per_px).
    background : float
        Mean background level in [0, 1].
    absorption_per_px : float
        Attenuation (transmit) or emission (emit) per px of PDMS crossed; in
        relief, the brightening per unit slope of the path length.
    rim_depth, rim_px : float
        Darkening by refraction at the steep outer wall: depth in [0, 1] and
        decay length, px.
    lumen_rim_depth : float
        Darkening at the lumen's wall (the lumen shows as a lighter band).
    opaque : float
        Extra uniform attenuation inside the tube (dark tube), in [0, 1].
    contrast : float
        Scales every attenuation: 1 full contrast, 0.3 low contrast.
    pipette_depth : float
        Contrast of the glass pipette relative to the tube's.
    gradient, vignetting : float
        Relative illumination change across the image and towards its corners.
    dust : int
        Number of dust specks (fixed across frames).
    texture : float
        Relative amplitude of a mottled background fixed across frames (a
        textured substrate or a dirty slide): the sum of smooth random fields
        at 2, 6 and 20 px, each of this standard deviation; 0 for none.
    flicker : float
        Standard deviation of the frame-to-frame illumination gain.
    photons : float
        Photo-electrons at full scale (shot noise); 0 turns shot noise off.
    read_noise : float
        Gaussian noise, fraction of full scale.
    blur_px : float
        Extra defocus blur (Gaussian sigma), px, on top of the optics' 0.5 px.
    shear_deg : float
        Relief only: the shear direction, deg counter-clockwise from the
        image's +x with y up; a flank whose inward normal faces it shows bright.
    """

    name: str = "transmitted"
    mode: str = "transmit"
    background: float = 0.78
    absorption_per_px: float = 0.006
    rim_depth: float = 0.65
    rim_px: float = 2.5
    lumen_rim_depth: float = 0.25
    opaque: float = 0.0
    contrast: float = 1.0
    pipette_depth: float = 0.6
    gradient: float = 0.12
    vignetting: float = 0.15
    dust: int = 12
    texture: float = 0.0
    flicker: float = 0.01
    photons: float = 4000.0
    read_noise: float = 0.006
    blur_px: float = 0.0
    shear_deg: float = 45.0

    def __post_init__(self):
        if self.mode not in ("transmit", "emit", "relief"):
            raise ValueError(
                f"look mode must be 'transmit', 'emit' or 'relief', got {self.mode!r}")
        if not np.isfinite(self.shear_deg):
            raise ValueError(f"look shear_deg must be a finite angle, got {self.shear_deg!r}")
        for name in ("background", "rim_depth", "lumen_rim_depth", "opaque", "contrast",
                     "pipette_depth"):
            value = getattr(self, name)
            if not (np.isfinite(value) and 0 <= value <= 1):
                raise ValueError(f"look {name} must be in [0, 1], got {value!r}")
        for name in ("absorption_per_px", "rim_px", "gradient", "vignetting", "texture",
                     "flicker", "photons", "read_noise", "blur_px"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"look {name} must be a non-negative number, got {value!r}")
        if int(self.dust) != self.dust or self.dust < 0:
            raise ValueError(f"look dust must be a non-negative whole number, got {self.dust!r}")

    def as_dict(self) -> dict:
        return asdict(self)

    def replace(self, **changes) -> Look:
        return replace(self, **changes)


LOOKS = {
    "transmitted": Look(),
    "opaque": Look(name="opaque", absorption_per_px=0.0, rim_depth=0.2, lumen_rim_depth=0.0,
                   opaque=0.7, background=0.82),
    "fluorescent": Look(name="fluorescent", mode="emit", background=0.05,
                        absorption_per_px=0.012, rim_depth=0.0, lumen_rim_depth=0.0,
                        pipette_depth=0.15, gradient=0.2, vignetting=0.3, dust=6,
                        photons=1500.0),
    "low_contrast": Look(name="low_contrast", contrast=0.3, gradient=0.2, vignetting=0.25,
                         dust=20, flicker=0.02, read_noise=0.008),
    "dic": Look(name="dic", mode="relief", background=0.5, absorption_per_px=0.15,
                rim_depth=0.0, lumen_rim_depth=0.0, pipette_depth=0.5, gradient=0.05,
                vignetting=0.1, dust=8, photons=3000.0, shear_deg=-45.0),
}


def get_look(spec) -> Look:
    """A :class:`Look` from a name in :data:`LOOKS`, a dict of fields, or a Look."""
    if isinstance(spec, Look):
        return spec
    if isinstance(spec, dict):
        fields = dict(spec)
        base = LOOKS.get(fields.get("name", "transmitted"), Look())
        unknown = set(fields) - set(Look.__dataclass_fields__)
        if unknown:
            raise ValueError(f"unknown look setting(s): {', '.join(sorted(unknown))}")
        return base.replace(**fields)
    if isinstance(spec, str) and spec in LOOKS:
        return LOOKS[spec]
    raise ValueError(f"unknown look {spec!r}; choose one of {', '.join(LOOKS)}")
