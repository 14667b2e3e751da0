"""Synthetic microscope frames of a microtube, with their ground truth.

The tube's axis in every frame is the line-segment model's chain
(:func:`models.ls_shape`) for the frame's pressure. Within one section all
segments share one tilt, so the chain's vertices lie exactly on a circle: the
renderer draws each section as that circular arc (the sagitta between two
vertices is below 1e-4 px) and the truth lists points of the chain itself.

Every pixel near the tube gets its arc-length position ``s`` and signed
distance ``d`` from the axis in closed form (no rasterised distance map), and
its value from a 1-D cross-section profile that is pre-integrated over the
pixel and the optics' point-spread function — so edges are anti-aliased and a
symmetric profile is centred on the true axis to rounding. The tube is cut
into pieces that turn at most 90°; a pixel belongs to at most one piece of a
stretch of tube, but to several pieces where the tube crosses itself, and
those layers multiply (transmitted light) or add (fluorescence), as in a real
projection.

Coordinates follow the tracker (see :mod:`pipeline.schema`): a pixel centre
(col, row) is at (col, row); internally the complex number ``col − 1j·row``
(y up); in micrometres ``x_um = col·scale``, ``y_um = −row·scale``.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np
import pandas as pd

from models import LSParams, get_sample, ls_shape, ls_tilts
from models.line_segment import _layout

from . import schema as S
from .atomic import atomic_dir
from .looks import Look, get_look

# the optics' point-spread function (Gaussian sigma, px) and the pixel's box
_PSF_PX = 0.5
_EDGE_SIGMA = math.sqrt(_PSF_PX**2 + 1.0 / 12.0)
_LUT_STEP = 1.0 / 32.0
_PIECE_MAX_PX = 64.0
_PIECE_MAX_TURN = math.pi / 2
_PIPETTE_GLASS = 0.8      # inner/outer radius of the glass pipette
FORMATS = {"avi": "frames.avi", "mp4": "frames.mp4", "png": "frames", "tiff": "frames.tif"}


@dataclass(frozen=True)
class Scene:
    """Everything needed to regenerate a rendered scene bit for bit.

    Parameters
    ----------
    sample : str
        Catalogue id ("1"–"8") or path of a sample TOML.
    eps_min, eps_max, k_de_per_um, elongation, n_segments, p_max_mpa
        Line-segment model parameters of the truth (see :class:`models.LSParams`).
    pressures_mpa : tuple of float, optional
        One pressure per frame; default a linear ramp from 0 to p_max over
        ``n_frames``.
    n_frames : int
    fps : float
        Frame rate written into the video and the truth's ``time_s``.
    width, height : int
        Image size, px.
    um_per_px : float, optional
        Scale; default: the largest shape of the scene fills the image.
    base_px : (col, row), optional
        Where the tube leaves the pipette; default: the scene is centred.
    base_angle_deg : float
        Direction of the tube at its base, CCW from +x (y up), degrees.
    mirror : bool
        Curl clockwise instead of counter-clockwise.
    look : str or dict
        A name from :data:`pipeline.looks.LOOKS` or a dict of look settings.
    seed : int
        Seed of every random element (noise, flicker, dust).
    pipette_ratio : float
        Pipette outer radius as a fraction of the tube's outer radius at its
        base: under 1, the tube is slid over the pipette; over 1, it is pushed
        into the pipette and shows through its glass.
    drift_px : float
        Amplitude of a stage drift, px: the tube and its pipette wander on a
        smooth path (:meth:`drift`) while the camera's dust and illumination
        stay; 0 (default) for a still stage.
    """

    sample: str = "1"
    eps_min: float = 0.5
    eps_max: float = 0.6
    k_de_per_um: float = 0.0
    elongation: float = 1.0
    n_segments: int = 1000
    p_max_mpa: float | None = None
    pressures_mpa: tuple | None = None
    n_frames: int = 40
    fps: float = 10.0
    width: int = 1024
    height: int = 768
    um_per_px: float | None = None
    base_px: tuple | None = None
    base_angle_deg: float = 0.0
    mirror: bool = False
    look: str | dict = "transmitted"
    seed: int = 0
    pipette_ratio: float = 0.6
    margin_px: float = 20.0
    drift_px: float = 0.0
    notes: str = field(default="", compare=False)

    def __post_init__(self):
        object.__setattr__(self, "sample", str(self.sample))
        if self.pressures_mpa is not None:
            p = np.asarray(self.pressures_mpa, dtype=float)
            if p.ndim != 1 or p.size == 0 or not np.all(np.isfinite(p)) or np.any(p < 0):
                raise ValueError("pressures_mpa must be a non-empty list of finite pressures "
                                 ">= 0")
            object.__setattr__(self, "pressures_mpa", tuple(float(v) for v in p))
            object.__setattr__(self, "n_frames", p.size)
        for name in ("n_frames", "width", "height"):
            value = getattr(self, name)
            if int(value) != value or value < 1:
                raise ValueError(f"{name} must be a positive whole number, got {value!r}")
        if self.width < 32 or self.height < 32:
            raise ValueError(f"image must be at least 32x32 px, got {self.width}x{self.height}")
        for name in ("fps", "pipette_ratio"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        if not (np.isfinite(self.drift_px) and 0 <= self.drift_px <= self.margin_px / 2):
            raise ValueError(f"drift_px must be a number from 0 to half the margin "
                             f"({self.margin_px / 2:g} px), got {self.drift_px!r}")
        if self.um_per_px is not None and not (np.isfinite(self.um_per_px)
                                                and self.um_per_px > 0):
            raise ValueError(f"um_per_px must be a positive number, got {self.um_per_px!r}")
        if not np.isfinite(self.base_angle_deg):
            raise ValueError(f"base_angle_deg must be finite, got {self.base_angle_deg!r}")
        if self.base_px is not None:
            object.__setattr__(self, "base_px", tuple(float(v) for v in self.base_px))
        get_look(self.look)  # validate early

    # -- derived ------------------------------------------------------------------
    def params(self) -> LSParams:
        return LSParams(eps_min=self.eps_min, eps_max=self.eps_max,
                        k_de_per_um=self.k_de_per_um, elongation=self.elongation,
                        n_segments=self.n_segments, p_max_mpa=self.p_max_mpa)

    def pressures(self) -> np.ndarray:
        """Pressure of every frame, MPa."""
        if self.pressures_mpa is not None:
            return np.asarray(self.pressures_mpa, dtype=float)
        p_max = self.p_max_mpa or get_sample(self.sample).p_max_mpa
        if p_max is None:
            raise ValueError(f"sample {self.sample} has no p_max: set p_max_mpa")
        return np.linspace(0.0, p_max, self.n_frames)

    def drift(self) -> np.ndarray:
        """The stage's offset on every frame, px (complex: col + 1j·y, y up),
        0 on the first: two slow sines on each axis, their phases from the
        seed, within ``drift_px`` of the start."""
        t = np.arange(self.n_frames) / max(self.n_frames - 1, 1)
        if self.drift_px == 0:
            return np.zeros(self.n_frames, complex)
        phase = np.random.default_rng([self.seed, 5]).uniform(0, 2 * np.pi, 4)
        path = (np.sin(2 * np.pi * 0.7 * t + phase[0])
                + 0.4 * np.sin(2 * np.pi * 2.1 * t + phase[1])
                + 1j * (np.sin(2 * np.pi * 0.5 * t + phase[2])
                        + 0.4 * np.sin(2 * np.pi * 1.7 * t + phase[3])))
        path = path - path[0]
        return self.drift_px * path / max(float(np.abs(path).max()), 1e-12)

    def as_dict(self) -> dict:
        out = asdict(self)
        out["pressures_mpa"] = list(self.pressures_mpa) if self.pressures_mpa else None
        out["base_px"] = list(self.base_px) if self.base_px else None
        return out

    @classmethod
    def from_dict(cls, data: dict) -> Scene:
        known = {f.name for f in fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise ValueError(f"unknown scene setting(s): {', '.join(sorted(unknown))}")
        return cls(**data)

    def replace(self, **changes) -> Scene:
        data = {f.name: getattr(self, f.name) for f in fields(self)}
        data.update(changes)
        if "n_frames" in changes and "pressures_mpa" not in changes:
            data["pressures_mpa"] = None
        return Scene(**data)


@dataclass(frozen=True)
class Layout:
    """Where the scene sits in the image: scale, base point (px) and orientation."""

    um_per_px: float
    base: complex          # col − 1j·row of the base
    angle_rad: float       # direction of the base tangent, CCW, y up
    mirror: bool

    def to_image(self, z_um):
        """Model-frame points (µm, complex) → image points (px, complex y up)."""
        z = np.conj(z_um) if self.mirror else np.asarray(z_um)
        return self.base + np.exp(1j * self.angle_rad) * z / self.um_per_px


def _outer_radius_um(sample) -> np.ndarray:
    return sample.r_in_um + 0.5 * (sample.t_top_um + sample.t_bot_um)


def truth_shapes(scene: Scene, n_points: int = 2):
    """Model shapes (µm, base at the origin along +x) of every frame, batched."""
    sample = get_sample(scene.sample)
    return ls_shape(sample, scene.pressures(), scene.params(), n_points=n_points)


def scene_layout(scene: Scene) -> Layout:
    """Scale and base point that keep the tube (and some pipette) inside the image.

    Raises
    ------
    ValueError
        If a given scale or base point puts part of the tube outside the image.
    """
    sample = get_sample(scene.sample)
    shapes = truth_shapes(scene, n_points=401)
    r_out = float(_outer_radius_um(sample).max())
    z = shapes.x_um + 1j * shapes.y_um
    if scene.mirror:
        z = np.conj(z)
    angle = math.radians(scene.base_angle_deg)
    z = np.exp(1j * angle) * z.ravel()
    # keep a stub of pipette (two tube diameters) in view behind the base
    z = np.concatenate([z, [-4 * r_out * np.exp(1j * angle)]])
    lo = complex(z.real.min() - r_out, z.imag.min() - r_out)
    hi = complex(z.real.max() + r_out, z.imag.max() + r_out)
    room_w = scene.width - 2 * scene.margin_px
    room_h = scene.height - 2 * scene.margin_px
    if room_w <= 0 or room_h <= 0:
        raise ValueError(f"image {scene.width}x{scene.height} px is too small for margins of "
                         f"{scene.margin_px} px")
    scale = scene.um_per_px or max((hi - lo).real / room_w, (hi - lo).imag / room_h)
    if scene.base_px is not None:
        base = complex(scene.base_px[0], -scene.base_px[1])
    else:
        # centre the scene, then slide it back along the pipette until the stub
        # meets the margin: the holder enters from the image border, as in a lab
        centre_img = complex(scene.width - 1, -(scene.height - 1)) / 2
        base = centre_img - (lo + hi) / 2 / scale
        back = -np.exp(1j * angle)
        lo_img, hi_img = base + lo / scale, base + hi / scale
        room = []
        m = scene.margin_px
        if back.real > 1e-9:
            room.append((scene.width - 1 - m - hi_img.real) / back.real)
        if back.real < -1e-9:
            room.append((m - lo_img.real) / back.real)
        if back.imag > 1e-9:
            room.append((-m - hi_img.imag) / back.imag)
        if back.imag < -1e-9:
            room.append((-(scene.height - 1 - m) - lo_img.imag) / back.imag)
        base += max(0.0, min(room)) * back
    layout = Layout(scale, base, angle, scene.mirror)
    # the tube itself (not the pipette stub) must lie inside the image
    zt = layout.to_image(shapes.x_um + 1j * shapes.y_um).ravel()
    r_px = r_out / scale
    if (zt.real.min() - r_px < 0 or zt.real.max() + r_px > scene.width - 1
            or -zt.imag.min() + r_px > scene.height - 1 or -zt.imag.max() - r_px < 0):
        raise ValueError(f"the tube leaves the {scene.width}x{scene.height} image at "
                         f"{scale:g} um/px: give a larger um_per_px or leave it unset")
    return layout


# -- cross-section profiles -----------------------------------------------------------
def _smooth(values: np.ndarray, step: float, sigma: float) -> np.ndarray:
    """Convolve a finely sampled profile with the pixel box and a Gaussian PSF."""
    from scipy.ndimage import gaussian_filter1d, uniform_filter1d

    box = max(1, int(round(1.0 / step)))
    out = uniform_filter1d(values, box, mode="nearest")
    return gaussian_filter1d(out, sigma / step, mode="nearest")


@dataclass(frozen=True)
class _Profile:
    d0: float
    step: float
    values: np.ndarray      # attenuation 1 − T (transmit) or emission (emit), smoothed
    reach: float            # |d| beyond which the profile is zero, px

    def __call__(self, d):
        return np.interp(d, self.d0 + self.step * np.arange(self.values.size), self.values,
                         left=0.0, right=0.0)


def _tube_profile(look: Look, r_out: float, r_lumen: float, lumen_offset: float,
                  depth: float = 1.0) -> _Profile:
    """Attenuation/emission across a tube of outer radius ``r_out`` (px)."""
    reach = r_out + 4 * _EDGE_SIGMA + 2
    d = np.arange(-reach, reach + _LUT_STEP / 2, _LUT_STEP)
    inside = np.abs(d) < r_out
    in_lumen = np.abs(d - lumen_offset) < r_lumen
    path = (2 * np.sqrt(np.clip(r_out**2 - d**2, 0, None))
            - 2 * np.sqrt(np.clip(r_lumen**2 - (d - lumen_offset) ** 2, 0, None)))
    path = np.clip(path, 0, None)
    if look.mode in ("emit", "relief"):
        values = look.absorption_per_px * path
    else:
        rim = look.rim_depth * inside * np.exp(-(r_out - np.abs(d)) / max(look.rim_px, 1e-3))
        lrim = look.lumen_rim_depth * in_lumen * np.exp(
            -(r_lumen - np.abs(d - lumen_offset)) / max(look.rim_px, 1e-3))
        trans = np.exp(-look.absorption_per_px * path) * (1 - rim) * (1 - lrim)
        trans *= 1 - look.opaque * inside
        values = 1 - trans
    values = np.clip(values * look.contrast * depth, 0, None)
    return _Profile(float(d[0]), _LUT_STEP, _smooth(values, _LUT_STEP, _PSF_PX), reach)


def _end_step(x):
    """Pre-integrated unit step (pixel box and PSF) at x = 0: 1 for x ≫ 0."""
    from scipy.special import ndtr

    return ndtr(x / _EDGE_SIGMA)


# -- the tube as arc pieces -------------------------------------------------------------
@dataclass(frozen=True)
class _Piece:
    z0: complex            # start point, px
    heading: float         # tangent direction at the start, rad
    kappa: float           # curvature, 1/px (CCW positive)
    length: float          # px
    profile: int           # index into the profile list
    first: bool            # owns s < 0 (fades out over the base step)
    last: bool             # owns s ≥ length (fades out over the tip step)


def _arc_point(piece: _Piece, s):
    k = piece.kappa
    if abs(k) * max(abs(np.max(s)), abs(np.min(s)), 1.0) < 1e-12:
        return piece.z0 + np.exp(1j * piece.heading) * s
    return piece.z0 + np.exp(1j * piece.heading) * (np.expm1(1j * k * s) / (1j * k))


def _sections_px(scene: Scene, layout: Layout, pressure: float):
    """Arcs (start, heading, curvature, length, section index) in px for one frame."""
    sample = get_sample(scene.sample)
    params = scene.params()
    theta, counts, stretch = ls_tilts(sample, pressure, params)
    theta = np.atleast_1d(theta).ravel()
    seg = _layout(sample, params.n_segments)[1] * float(stretch)
    verts = ls_shape(sample, pressure, params, n_points=None)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    sign = -1.0 if layout.mirror else 1.0
    arcs = []
    for i, v in enumerate(starts):
        h_prev = float(verts.phi_rad[v]) if v > 0 else 0.0
        th = float(theta[i])
        heading = h_prev + th / 2
        half = th / 2
        if abs(half) < 1e-12:
            kappa, length = 0.0, counts[i] * seg[i]
        else:
            kappa = 2 * math.sin(half) / seg[i]
            length = counts[i] * seg[i] * half / math.sin(half)
        z0 = complex(verts.x_um[v], verts.y_um[v])
        arcs.append((layout.to_image(z0), layout.angle_rad + sign * heading,
                     sign * kappa * layout.um_per_px, length / layout.um_per_px, i))
    return arcs


def _pieces(arcs) -> list[_Piece]:
    out = []
    for z0, heading, kappa, length, sec in arcs:
        n = max(1, math.ceil(length / _PIECE_MAX_PX), math.ceil(abs(kappa) * length
                                                                  / _PIECE_MAX_TURN))
        step = length / n
        for _ in range(n):
            piece = _Piece(z0, heading, kappa, step, sec, False, False)
            out.append(piece)
            z0 = complex(_arc_point(piece, np.array([step]))[0])
            heading = heading + kappa * step
    out[0] = _Piece(**{**asdict(out[0]), "first": True})
    out[-1] = _Piece(**{**asdict(out[-1]), "last": True})
    return out


def _stamp(piece: _Piece, profile: _Profile, shape, *, base_fade=True, plug=None):
    """(row slice, col slice, value array) of one piece's contribution, or None."""
    rows, cols = shape
    pad = profile.reach + 1.5
    ext0 = pad if piece.first else 0.0
    ext1 = pad if piece.last else 0.0
    s_probe = np.linspace(-ext0, piece.length + ext1, 9)
    pts = _arc_point(piece, s_probe)
    c0 = max(int(math.floor(pts.real.min() - pad)), 0)
    c1 = min(int(math.ceil(pts.real.max() + pad)) + 1, cols)
    r0 = max(int(math.floor(-pts.imag.max() - pad)), 0)
    r1 = min(int(math.ceil(-pts.imag.min() + pad)) + 1, rows)
    if c0 >= c1 or r0 >= r1:
        return None
    cc = np.arange(c0, c1, dtype=float)[None, :]
    rr = np.arange(r0, r1, dtype=float)[:, None]
    rel = ((cc - piece.z0.real) + 1j * (-rr - piece.z0.imag)) * np.exp(-1j * piece.heading)
    u, v = rel.real, rel.imag
    k = piece.kappa
    if k == 0.0:
        s, d = u, v
    else:
        # stable forms of the arc position and the signed distance (left positive):
        # no cancellation as κ → 0
        r2 = u * u + v * v
        s = np.arctan2(k * u, 1 - k * v) / k
        d = (2 * v - k * r2) / (1 + np.sqrt(np.clip(1 - 2 * k * v + k * k * r2, 0, None)))
    own = np.abs(d) < profile.reach
    if not piece.first:
        own &= s >= 0
    if not piece.last:
        own &= s < piece.length
    if not own.any():
        return None
    value = profile(d)
    if piece.first and base_fade:
        value = value * _end_step(s)
    if piece.last and plug is not None:
        # the sealed tip: a solid PDMS plug, its end face darkened by refraction
        solid, plug_px, rim_depth, rim_px, r_out = plug
        to_end = piece.length - s
        w = _end_step(plug_px - to_end)
        value = value * (1 - w) + solid(d) * w
        if rim_depth > 0:
            rim = rim_depth * np.exp(-np.clip(to_end, 0, None) / rim_px) * _end_step(
                r_out - np.abs(d))
            value = 1 - (1 - value) * (1 - rim)
    if piece.last:
        value = value * _end_step(piece.length - s)
    return slice(r0, r1), slice(c0, c1), np.where(own, value, 0.0)


# -- frames ------------------------------------------------------------------------------
class Renderer:
    """Renders the frames of one scene; frames are independent given the seed."""

    def __init__(self, scene: Scene):
        self.scene = scene
        self.look = get_look(scene.look)
        self.sample = get_sample(scene.sample)
        self.layout = scene_layout(scene)
        self.pressures = scene.pressures()
        self.drift = scene.drift()
        scale = self.layout.um_per_px
        r_out = _outer_radius_um(self.sample) / scale
        # the void sits (t_t − t_b)/2 from the outer centre toward the thin (bottom)
        # wall, which is on the outside of the bend: the right when curling CCW
        ecc = 0.5 * (self.sample.t_top_um - self.sample.t_bot_um) / scale
        sign = 1.0 if scene.mirror else -1.0
        self.profiles = [_tube_profile(self.look, float(r), self.sample.r_in_um / scale,
                                       float(sign * e)) for r, e in zip(r_out, ecc, strict=True)]
        solid = _tube_profile(self.look, float(r_out[-1]), 0.0, 0.0)
        rim = self.look.rim_depth * self.look.contrast if self.look.mode == "transmit" else 0.0
        self.plug = (solid, max(2.0, float(self.sample.t_top_um[-1]) / scale), rim,
                     max(self.look.rim_px, 0.5), float(r_out[-1]))
        rp = scene.pipette_ratio * float(r_out[0])
        # the pipette is glass whatever the tube is made of: thin walls, refraction rims
        # (in relief its path shows as the tube's does: glass is as clear as PDMS)
        glass = self.look.replace(opaque=0.0, rim_depth=0.5, lumen_rim_depth=0.2,
                                  absorption_per_px=(self.look.absorption_per_px
                                                     if self.look.mode == "relief" else 0.01))
        self.pipette = _tube_profile(glass, rp, _PIPETTE_GLASS * rp, 0.0,
                                     depth=self.look.pipette_depth)
        self.illumination = self._illumination()
        self.dust = self._dust()

    def __len__(self):
        return self.scene.n_frames

    def _illumination(self) -> np.ndarray:
        look, sc = self.look, self.scene
        rng = np.random.default_rng([sc.seed, 1])
        rows, cols = sc.height, sc.width
        y, x = np.mgrid[0:rows, 0:cols].astype(np.float32)
        direction = rng.uniform(0, 2 * np.pi)
        diag = math.hypot(rows, cols)
        ramp = ((x - cols / 2) * math.cos(direction) + (y - rows / 2) * math.sin(direction)) / diag
        cx, cy = cols * rng.uniform(0.35, 0.65), rows * rng.uniform(0.35, 0.65)
        rho2 = ((x - cx) ** 2 + (y - cy) ** 2) / (diag / 2) ** 2
        return ((1 + 2 * look.gradient * ramp) * (1 - look.vignetting * rho2)).astype(np.float32)

    def _dust(self) -> np.ndarray:
        """Fixed specks: a transmission map (1 = clean)."""
        look, sc = self.look, self.scene
        dust = np.ones((sc.height, sc.width), np.float32)
        rng = np.random.default_rng([sc.seed, 2])
        for _ in range(int(look.dust)):
            cx, cy = rng.uniform(0, sc.width), rng.uniform(0, sc.height)
            sigma = rng.uniform(0.8, 4.0)
            depth = rng.uniform(0.1, 0.5) * max(look.contrast, 0.3)
            r = int(math.ceil(4 * sigma))
            c0, c1 = max(int(cx) - r, 0), min(int(cx) + r + 1, sc.width)
            r0, r1 = max(int(cy) - r, 0), min(int(cy) + r + 1, sc.height)
            if c0 >= c1 or r0 >= r1:
                continue
            yy, xx = np.mgrid[r0:r1, c0:c1]
            blob = depth * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * sigma**2))
            dust[r0:r1, c0:c1] *= (1 - blob).astype(np.float32)
        if look.texture > 0:
            import cv2

            rng = np.random.default_rng([sc.seed, 4])
            mottle = np.zeros_like(dust)
            for sigma in (2.0, 6.0, 20.0):
                field = cv2.GaussianBlur(rng.standard_normal(dust.shape, dtype=np.float32),
                                         (0, 0), sigma)
                mottle += look.texture * field / max(float(field.std()), 1e-12)
            dust *= np.clip(1 + mottle, 0.05, None)
        return dust

    def tube_layers(self, index: int) -> np.ndarray:
        """Noise-free tube + pipette: transmission (transmit), emission (emit) or
        path length times the relief's gain (relief) map."""
        sc, look = self.scene, self.look
        shape = (sc.height, sc.width)
        emit = look.mode in ("emit", "relief")   # (relief: the path lengths add)
        acc = np.zeros(shape, np.float64) if emit else np.ones(shape, np.float64)

        def apply(stamp):
            if stamp is None:
                return
            rs, cs, value = stamp
            if emit:
                acc[rs, cs] += value
            else:
                acc[rs, cs] *= 1 - value

        layout = self.layout
        if sc.drift_px:
            layout = replace(layout, base=layout.base + self.drift[index])
        arcs = _sections_px(sc, layout, float(self.pressures[index]))
        pipe_len = 2.0 * math.hypot(sc.width, sc.height)
        behind = _Piece(layout.base, layout.angle_rad + math.pi, 0.0, pipe_len, 0, True, False)
        apply(_stamp(behind, self.pipette, shape))
        if sc.pipette_ratio > 1.0:
            # a pipette wider than the tube holds it inside: seen through the glass
            apply(_stamp(behind, self.profiles[0], shape))
        for piece in _pieces(arcs):
            apply(_stamp(piece, self.profiles[piece.profile], shape, plug=self.plug))
        return acc

    def frame(self, index: int) -> np.ndarray:
        """Frame ``index`` as float32 in [0, 1]."""
        if not 0 <= index < len(self):
            raise IndexError(f"frame {index} out of range 0..{len(self) - 1}")
        sc, look = self.scene, self.look
        rng = np.random.default_rng([sc.seed, 3, index])
        gain = 1 + look.flicker * rng.standard_normal()
        layers = self.tube_layers(index).astype(np.float32)
        if look.mode == "emit":
            img = self.illumination * gain * (look.background + layers) * self.dust
        elif look.mode == "relief":
            # the path's slope along the shear (image rows run down: y = −row)
            d_row, d_col = np.gradient(layers)
            shear = math.radians(look.shear_deg)
            slope = d_col * math.cos(shear) - d_row * math.sin(shear)
            img = look.background * self.illumination * gain * (1 + slope) * self.dust
        else:
            img = look.background * self.illumination * gain * layers * self.dust
        if look.blur_px > 0:
            import cv2

            img = cv2.GaussianBlur(img, (0, 0), look.blur_px)
        shot = np.clip(img, 0, None) / look.photons if look.photons else 0.0
        # shot noise in its Gaussian limit (≥ 1000 photo-electrons at full scale)
        sd = np.sqrt(shot + look.read_noise**2)
        img = img + sd * rng.standard_normal(img.shape, dtype=np.float32)
        return np.clip(img, 0, 1).astype(np.float32)

    def __iter__(self):
        for i in range(len(self)):
            yield self.frame(i)


# -- truth -----------------------------------------------------------------------------
def truth_tables(scene: Scene, layout: Layout | None = None):
    """(tracks, centrelines, pressure) DataFrames of the scene's truth, tracker columns.

    Centreline points are ≤ 0.9 px apart, base to tip.
    """
    layout = layout or scene_layout(scene)
    sample = get_sample(scene.sample)
    p = scene.pressures()
    scale = layout.um_per_px
    length_max = sample.length_um * max(1.0, float(scene.elongation))
    n_points = int(math.ceil(length_max / scale / 0.9)) + 1
    shapes = ls_shape(sample, p, scene.params(), n_points=n_points)
    z = (layout.to_image(shapes.x_um + 1j * shapes.y_um) + scene.drift()[:, None]) * scale
    sign = -1.0 if scene.mirror else 1.0
    frames = np.arange(p.size)
    time_s = frames / scene.fps
    base_angle = math.degrees(layout.angle_rad)
    tracks = pd.DataFrame({
        S.FRAME: frames, S.TIME: time_s, S.PRESSURE: p,
        S.BEND: sign * np.degrees(shapes.bend_angle_rad),
        S.TIP_X: z[:, -1].real, S.TIP_Y: z[:, -1].imag,
        S.BASE_X: z[:, 0].real, S.BASE_Y: z[:, 0].imag,
        S.LENGTH: shapes.s_um[:, -1], S.STATUS: S.STATUS_OK,
        S.BASE_ANGLE: base_angle,
    })[S.TRUTH_COLUMNS]
    lines = pd.DataFrame({
        S.FRAME: np.repeat(frames, n_points), S.S: shapes.s_um.ravel(),
        S.X: z.real.ravel(), S.Y: z.imag.ravel(),
    })[S.CENTRELINE_COLUMNS]
    pressure = pd.DataFrame({S.FRAME: frames, S.TIME: time_s, S.PRESSURE: p})[
        S.PRESSURE_COLUMNS]
    return tracks, lines, pressure


def render_scene(scene: Scene, out_dir, *, fmt: str = "avi", bit_depth: int = 8,
                 progress=None) -> Path:
    """Render ``scene`` into ``out_dir``: frames, truth CSVs, pressure log, scene.json.

    The folder is written atomically (it appears complete or not at all). An
    existing folder is replaced only if it holds a previous scene (scene.json).

    Parameters
    ----------
    fmt : {"avi", "mp4", "png", "tiff"}
        MJPG AVI, MP4, a folder of PNGs, or a multi-page TIFF.
    bit_depth : {8, 16}
        16 only for png and tiff.
    progress : callable, optional
        ``progress(done, total)`` after every frame.
    """
    from .frames import write_frames

    if fmt not in FORMATS:
        raise ValueError(f"unknown format {fmt!r}; choose one of {', '.join(FORMATS)}")
    if bit_depth not in (8, 16):
        raise ValueError(f"bit depth must be 8 or 16, got {bit_depth!r}")
    if bit_depth == 16 and fmt in ("avi", "mp4"):
        raise ValueError(f"{fmt} video is 8-bit: use --format png or tiff for 16-bit frames")
    out_dir = Path(out_dir)
    if out_dir.exists() and (not out_dir.is_dir() or (
            any(out_dir.iterdir()) and not (out_dir / S.SCENE_FILE).exists())):
        raise ValueError(f"{out_dir} exists and is not a rendered scene: refusing to "
                         "overwrite it")
    renderer = Renderer(scene)
    tracks, lines, pressure = truth_tables(scene, renderer.layout)

    def frames():
        for i in range(len(renderer)):
            yield renderer.frame(i)
            if progress is not None:
                progress(i + 1, len(renderer))

    record = {
        "scene": scene.as_dict(),
        "layout": {"um_per_px": renderer.layout.um_per_px,
                   "base_px": [renderer.layout.base.real, -renderer.layout.base.imag],
                   "base_angle_deg": math.degrees(renderer.layout.angle_rad),
                   "mirror": renderer.layout.mirror},
        "look": renderer.look.as_dict(),
        "frames_file": FORMATS[fmt],
        "format": fmt,
        "bit_depth": bit_depth,
        "truth": "line-segment model chain (models.ls_shape) at the parameters above; "
                 "coordinates as tracks.csv (x_um = col*scale, y_um = -row*scale)",
        "regenerate": f"microtube render --scene {S.SCENE_FILE} --out DIR",
    }
    with atomic_dir(out_dir) as tmp:
        write_frames(frames(), tmp / FORMATS[fmt], fps=scene.fps, bit_depth=bit_depth)
        tracks.to_csv(tmp / S.TRUTH_TRACKS_FILE, index=False, float_format="%.9g")
        lines.to_csv(tmp / S.TRUTH_CENTRELINES_FILE, index=False, float_format="%.8g")
        pressure.to_csv(tmp / S.PRESSURE_FILE, index=False)
        (tmp / S.SCENE_FILE).write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    return out_dir


def load_scene(path) -> tuple[Scene, str, int]:
    """(scene, format, bit depth) from a scene.json written by :func:`render_scene`."""
    path = Path(path)
    if path.is_dir():
        path = path / S.SCENE_FILE
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"{path}: no such scene file") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a readable scene file ({exc})") from None
    if not isinstance(record, dict) or "scene" not in record:
        raise ValueError(f"{path}: not a scene file (no 'scene' entry)")
    return (Scene.from_dict(record["scene"]), record.get("format", "avi"),
            int(record.get("bit_depth", 8)))


def default_scene(sample, *, n_frames: int = 40, seed: int = 0, look="transmitted",
                  **changes) -> Scene:
    """A scene of a catalogue sample inflated from 0 to its p_max, with plausible strains.

    The strain range is set so that the bend at p_max is that of the paper's
    experiment (Table 2) for samples #1–#3, and about 270° otherwise.
    """
    from models import PAPER_TABLE2

    spec = get_sample(sample)
    key = str(sample)
    p_max = changes.pop("p_max_mpa", None) or spec.p_max_mpa or 0.15
    target = PAPER_TABLE2.get(int(key), {}).get("experiment_deg", 270.0) if key.isdigit() \
        else 270.0
    k = changes.pop("k_de_per_um", -0.002 if _de_spread(spec) > 0.2 else 0.0)
    eps_max = changes.pop("eps_max", None) or strain_for_angle(spec, target, k=k, p_max=p_max)
    return Scene(sample=key, eps_max=eps_max, k_de_per_um=k, p_max_mpa=p_max,
                 n_frames=n_frames, seed=seed, look=look, **changes)


def _de_spread(sample) -> float:
    de = np.abs(sample.geometry.d_e_um)
    return float((de.max() - de.min()) / de.mean())


def strain_for_angle(sample, angle_deg: float, *, k: float = 0.0, eps_min: float = 0.5,
                     p_max: float | None = None, n_segments: int = 1000) -> float:
    """ε_max giving bend ``angle_deg`` at p_max (ε_min and k fixed), by root finding."""
    from scipy.optimize import brentq

    from models import ls_bend_angle

    p_max = p_max or sample.p_max_mpa

    def f(eps_max):
        params = LSParams(eps_min=eps_min, eps_max=eps_max, k_de_per_um=k, p_max_mpa=p_max,
                          n_segments=n_segments)
        return float(np.degrees(ls_bend_angle(sample, p_max, params))) - angle_deg

    return float(brentq(f, eps_min + 1e-9, eps_min + 5.0, xtol=1e-12))


def render_to_folder(sample, out, *, fmt: str | None = None, n_frames: int = 50, seed: int = 0,
                     look="transmitted", bit_depth: int | None = None, scene_file=None,
                     progress=None, **changes) -> Path:
    """The ``microtube render`` command: a default scene of ``sample`` (or a scene.json).

    ``fmt`` and ``bit_depth`` default to the scene file's own (so that a
    scene.json regenerates the same files), or to 8-bit AVI.
    """
    if scene_file is not None:
        scene, fmt_was, depth_was = load_scene(scene_file)
    else:
        scene = default_scene(sample, n_frames=n_frames, seed=seed, look=look, **changes)
        fmt_was, depth_was = "avi", 8
    return render_scene(scene, out, fmt=fmt or fmt_was,
                        bit_depth=bit_depth if bit_depth is not None else depth_was,
                        progress=progress)
