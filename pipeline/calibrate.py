"""Calibrate a model of one sample on its tracked shapes (paper §2.3–2.4).

The tracker's ``centrelines.csv`` gives, for every usable frame, the tube from
base to tip in µm (y up); ``tracks.csv`` gives the base point and base tangent.
Each frame's pressure comes from :mod:`pipeline.pressure` (a log or a ramp) or,
with neither, is fitted: the line-segment model takes p only as p/p_max, and its
tilt is (a function of Δε) × p/p_max, so every frame's ratio is a parameter of
its own except the most bent frame's, held at 1. The model shape
(base at the origin, base tangent along +x) is *placed* on each frame by
rotating it by the measured base angle and moving it to the measured base
point, and compared point by point at matched arc-length fractions
``u_j = j/M, j = 1..M`` of the whole centreline. The residuals are the x and y
components of those point-to-point differences, µm, over all frames, so that
their sum of squares is the sum of squared distances.

Models and their parameters (names as in the output JSON):

* ``"ls"`` — the line-segment model (Eqs. 9–12, :func:`models.ls_shape`).
  In its form the strains enter only through Δε = ε_max − ε_min, so ε_min is
  held at its default 0.5 and ε_max = ε_min + Δε is fitted (ε within
  [0.5, 1.2] by default). ``k_de`` (1/µm) is fitted only when the sections
  differ in |d_e| enough for the data to tell it from Δε, and ``elongation``
  λ only when the measured length changes with the pressure.
* ``"eb"`` — the multi-segment Euler–Bernoulli model (Eqs. 1–8,
  :func:`models.eb_shape`) with one effective modulus ``E_eff_mpa``.

Fitting: :func:`scipy.optimize.least_squares` (trust-region reflective, soft-L1
loss with ``f_scale`` a few pixels' worth of µm so that a mistracked frame does
not pull the fit, ``x_scale='jac'``), from a start found by a 1-D scan of the
main parameter on the measured tip angles. The Jacobian is by forward
differences, all parameter sets evaluated in one batched model call.

Statistics at the solution (see :func:`_statistics`):

* the robust loss is an M-estimator; at its minimum it is the weighted
  least-squares fit with the IRLS weights ``w = ρ'(z)``. SciPy's ``res.jac`` is
  scaled by ``sqrt(ρ' + 2ρ''z)`` for its Newton step (and clamped), which is not
  the weight we want, so the raw Jacobian is recomputed and each row weighted
  by ``sqrt(w)``. Covariance = ``s² (JᵀWJ)⁺`` with ``s² = Σ w r² / (n − p)``,
  the pseudo-inverse from an SVD of the column-normalised Jacobian with a rank
  cut;
* identifiability: a normalised singular value below ``NULL_TOL`` of the
  largest marks a near-null direction; the secondary parameter loading most on
  it (k, then λ) is fixed at its default and the fit repeated, and the output
  says why. A parameter at a bound is reported as not determined;
* points along one centreline are correlated, so the Jacobian standard errors
  are optimistic: the 95% intervals come from a bootstrap over frames (frames
  resampled with replacement). Each replicate is one Gauss–Newton step from the
  solution with the per-frame normal equations frozen there (a linearised
  bootstrap: exact for a model linear in its parameters, and the line-segment
  model is nearly linear in Δε) — 200 replicates cost well under a
  millisecond instead of 200 refits.
"""

from __future__ import annotations

import contextlib
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import sparse
from scipy.optimize import least_squares

from models import LSParams, eb_bend_angle, eb_shape, get_sample, ls_bend_angle, ls_shape
from models.line_segment import DEFAULT_EPS_MAX, DEFAULT_EPS_MIN, DEFAULT_SEGMENTS

from . import schema as S
from .atomic import atomic_path, write_csv, write_json
from .pressure import FramePressures, frame_pressures
from .robust import robust_sd

#: Arc-length fractions compared per frame.
DEFAULT_FRACTIONS = 100
#: Normalised singular value (relative to the largest) below which a direction is near-null.
NULL_TOL = 0.02
#: Bootstrap replicates for the 95% intervals.
DEFAULT_BOOTSTRAP = 200
#: Tracked lengths more than this far from the sample's length are refused.
LENGTH_TOL = 0.30
#: λ is fitted when the length's change over the pressure range exceeds this and 3 stderr.
ELONGATION_MIN_CHANGE = 0.005
#: Upper bound of a fitted p/p_max (the most bent frame is at 1).
RATIO_MAX = 1.5
#: Systematic heading error of the tracker at the tip (1 sd, degrees), taken as the
#: tracking accuracy target (median tip-angle error ≤ 0.5°, see reports/tracking).
TRACKING_SD_DEG = 0.25
#: Systematic relative error of the tracked length (1 sd); the tracker measures ≤ 0.25%.
TRACKING_LENGTH_SD = 0.0025
_RCOND = 1e-10


# -- results ---------------------------------------------------------------------------


@dataclass(frozen=True)
class ParameterEstimate:
    """One parameter of a calibration.

    Attributes
    ----------
    value : float
        Fitted or fixed value (units in the parameter's name).
    stderr : float or None
        Jacobian standard error scaled by the residual variance (None if fixed).
    ci95 : (float, float) or None
        95% interval (None if fixed): the bootstrap interval over frames widened,
        in quadrature, by ±1.96 ``tracking_sd``.
    tracking_sd : float or None
        Standard deviation from the tracker's systematic errors (None if fixed).
    fitted : bool
        True when the data determined it.
    reason : str
        Why it was fixed or not determined ("" when fitted).
    """

    value: float
    stderr: float | None = None
    ci95: tuple[float, float] | None = None
    fitted: bool = False
    reason: str = ""
    tracking_sd: float | None = None

    def to_dict(self) -> dict:
        return {"value": _num(self.value), "stderr": _num(self.stderr),
                "ci95": None if self.ci95 is None else [_num(v) for v in self.ci95],
                "tracking_sd": _num(self.tracking_sd),
                "fitted": bool(self.fitted), "reason": self.reason}


@dataclass(frozen=True)
class CalibrationResult:
    """Outcome of :func:`calibrate` (frozen; inputs are never changed).

    Attributes
    ----------
    model : str
        ``"ls"`` or ``"eb"``.
    sample : str
        Sample name.
    parameters : dict of str to ParameterEstimate
        ``eps_min, eps_max, k_de, elongation`` (ls) or ``E_eff_mpa`` (eb).
    correlation : dict of str to dict of str to float
        Correlations between the fitted parameters.
    rms_um, max_residual_um : float
        RMS and largest point-to-point distance over all used frames, µm.
    angle_rms_deg : float
        RMS of model − measured tip angle over the used frames, degrees.
    frames_used, frames_skipped : int
    pressure_source : str
    runtime_s : float
        Wall time of the fit, statistics and bootstrap (no file I/O), s.
    n_segments : int or None
        Line segments N of the ls model.
    p_max_mpa : float or None
        p_max of the ls model's pressure ratio.
    residuals : DataFrame
        One row per used frame (see :func:`calibrate`).
    singular_values : tuple of float
        Normalised singular values of the weighted Jacobian at the solution, for
        the shared parameters (each frame's own p/p_max, when fitted, projected out).
    notes : tuple of str
        What was decided along the way (skipped frames, mirroring, …).
    """

    model: str
    sample: str
    parameters: dict
    correlation: dict
    rms_um: float
    max_residual_um: float
    angle_rms_deg: float
    frames_used: int
    frames_skipped: int
    pressure_source: str
    runtime_s: float
    n_segments: int | None
    p_max_mpa: float | None
    residuals: pd.DataFrame = field(repr=False)
    singular_values: tuple = ()
    f_scale_um: float = float("nan")
    mirrored: bool = False
    success: bool = True
    message: str = ""
    notes: tuple = ()
    bootstrap: dict = field(default_factory=dict)
    _curves: dict = field(default_factory=dict, repr=False, compare=False)

    def value(self, name: str) -> float:
        return self.parameters[name].value

    @property
    def delta_eps(self) -> float:
        """Δε = ε_max − ε_min of an ls fit."""
        return self.value("eps_max") - self.value("eps_min")

    def to_dict(self) -> dict:
        """The JSON document of the issue (plus a few extra keys)."""
        return {
            "model": self.model,
            "sample": self.sample,
            "parameters": {k: p.to_dict() for k, p in self.parameters.items()},
            "correlation": {a: {b: _num(v) for b, v in row.items()}
                            for a, row in self.correlation.items()},
            "rms_um": _num(self.rms_um),
            "max_residual_um": _num(self.max_residual_um),
            "angle_rms_deg": _num(self.angle_rms_deg),
            "frames_used": int(self.frames_used),
            "frames_skipped": int(self.frames_skipped),
            "pressure_source": self.pressure_source,
            "runtime_s": _num(self.runtime_s),
            "n_segments": self.n_segments,
            "p_max_mpa": _num(self.p_max_mpa),
            "f_scale_um": _num(self.f_scale_um),
            "mirrored": bool(self.mirrored),
            "singular_values": [_num(v) for v in self.singular_values],
            "bootstrap": self.bootstrap,
            "success": bool(self.success),
            "message": self.message,
            "notes": list(self.notes),
        }

    def summary(self) -> str:
        """A few human-readable lines."""
        lines = [f"sample {self.sample}, model {self.model}"
                 + (f" (N = {self.n_segments})" if self.n_segments else "")
                 + f": {self.frames_used} frames used, {self.frames_skipped} skipped; "
                 f"pressure: {self.pressure_source}"]
        for name, p in self.parameters.items():
            if p.fitted:
                lo, hi = p.ci95 if p.ci95 is not None else (np.nan, np.nan)
                lines.append(f"  {name:<11} = {p.value:.6g} +- {p.stderr:.2g} "
                             f"(95% [{lo:.6g}, {hi:.6g}])")
            else:
                lines.append(f"  {name:<11} = {p.value:.6g}  not fitted: {p.reason}")
        lines.append(f"  residual rms {self.rms_um:.2f} um (max {self.max_residual_um:.1f} um), "
                     f"tip angle rms {self.angle_rms_deg:.2f} deg, {self.runtime_s:.3f} s")
        return "\n".join(lines)


# -- measured data ----------------------------------------------------------------------


@dataclass(frozen=True)
class FitData:
    """Measured shapes of the usable frames, resampled at matched arc-length fractions.

    Attributes
    ----------
    frame : (F,) int ndarray
    pressure_mpa : (F,) ndarray
    base : (F,) complex ndarray
        Base point x + iy, µm.
    base_angle_rad : (F,) ndarray
        Direction of the base tangent, rad, CCW from +x.
    points : (F, M) complex ndarray
        Measured centreline at fractions j/M, j = 1..M, of its length, µm.
    bend_deg : (F,) ndarray
        Tracked tip angle, degrees.
    length_um : (F,) ndarray
        Tracked length, µm.
    spacing_um : float
        Median spacing of the tracked centreline points (≈ 1 px), µm.
    """

    frame: np.ndarray
    pressure_mpa: np.ndarray
    base: np.ndarray
    base_angle_rad: np.ndarray
    points: np.ndarray
    bend_deg: np.ndarray
    length_um: np.ndarray
    spacing_um: float

    @property
    def n_frames(self) -> int:
        return self.frame.size

    @property
    def n_fractions(self) -> int:
        return self.points.shape[1]


def read_tracks(tracks_dir) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Read ``tracks.csv`` and ``centrelines.csv`` from a tracker output folder.

    Raises
    ------
    ValueError
        Missing folder, files or columns.
    """
    folder = Path(tracks_dir)
    if not folder.is_dir():
        raise ValueError(f"tracks folder not found: {folder}")
    tables = []
    for name, columns in ((S.TRACKS_FILE, S.TRACK_COLUMNS),
                          (S.CENTRELINES_FILE, S.CENTRELINE_COLUMNS)):
        path = folder / name
        if not path.is_file():
            raise ValueError(f"{name} not found in {folder}")
        try:
            table = pd.read_csv(path)
        except (OSError, ValueError, pd.errors.ParserError) as exc:
            raise ValueError(f"cannot read {path}: {str(exc).strip().splitlines()[0]}") from None
        missing = [c for c in columns if c not in table.columns and c != S.TIME]
        if missing:
            raise ValueError(f"{path} lacks column(s) {', '.join(missing)}")
        tables.append(table)
    return tables[0], tables[1]


def usable_frames(tracks: pd.DataFrame, centrelines: pd.DataFrame) -> tuple[np.ndarray, Counter]:
    """Frames with status ok, finite base, base angle and length, and a centreline.

    Returns
    -------
    frames : (F,) int ndarray
    skipped : Counter
        Reason → number of frames left out.
    """
    status = tracks[S.STATUS].astype(str).str.strip()
    skipped = Counter(status[status != S.STATUS_OK])
    ok = tracks[status == S.STATUS_OK]
    nums = ok[[S.BASE_X, S.BASE_Y, S.BASE_ANGLE, S.LENGTH, S.BEND]].apply(
        pd.to_numeric, errors="coerce")
    finite = np.isfinite(nums.to_numpy(dtype=float)).all(axis=1)
    if (~finite).any():
        skipped["ok but base, angle or length missing"] += int((~finite).sum())
    frames = ok[S.FRAME].to_numpy()[finite].astype(np.int64)
    counts = centrelines.groupby(S.FRAME).size()
    has_line = counts.reindex(frames).fillna(0).to_numpy() >= 2
    if (~has_line).any():
        skipped["ok but no centreline"] += int((~has_line).sum())
    return frames[has_line], skipped


def prepare_data(tracks: pd.DataFrame, centrelines: pd.DataFrame, pressures: FramePressures, *,
                 n_fractions: int = DEFAULT_FRACTIONS) -> FitData:
    """Resample the measured centrelines of ``pressures.frame`` at fractions j/M of their length."""
    frames = np.asarray(pressures.frame, dtype=np.int64)
    row = tracks.drop_duplicates(S.FRAME).set_index(S.FRAME).loc[frames]
    lines = centrelines[centrelines[S.FRAME].isin(frames)][[S.FRAME, S.S, S.X, S.Y]]
    lines = lines.apply(pd.to_numeric, errors="coerce").dropna()
    lines = lines.sort_values([S.FRAME, S.S], kind="stable")
    u = np.arange(1, n_fractions + 1) / n_fractions
    points = np.empty((frames.size, n_fractions), complex)
    spacing = []
    groups = {int(f): g for f, g in lines.groupby(S.FRAME)}
    for i, f in enumerate(frames):
        g = groups[int(f)]
        s = g[S.S].to_numpy(float)
        x, y = g[S.X].to_numpy(float), g[S.Y].to_numpy(float)
        s = s - s[0]
        at = u * s[-1]
        points[i] = np.interp(at, s, x) + 1j * np.interp(at, s, y)
        spacing.append(np.median(np.diff(s)))
    return FitData(
        frame=frames, pressure_mpa=np.asarray(pressures.pressure_mpa, float),
        base=row[S.BASE_X].to_numpy(float) + 1j * row[S.BASE_Y].to_numpy(float),
        base_angle_rad=np.radians(row[S.BASE_ANGLE].to_numpy(float)),
        points=points, bend_deg=row[S.BEND].to_numpy(float),
        length_um=row[S.LENGTH].to_numpy(float), spacing_um=float(np.median(spacing)))


# -- models ------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Spec:
    """A model as the fitter sees it: full parameter vector, names, defaults, bounds."""

    names: tuple            # internal names of the full parameter vector
    default: np.ndarray     # values of fixed parameters
    lower: np.ndarray
    upper: np.ndarray
    shapes: object          # theta (K, P) -> (tube-frame points (K, F, M), tip angle (K, F))
    tips: object            # theta (K, P) -> tip angle (K, F), rad (cheap: no shape)
    per_frame: np.ndarray | None = None  # (F,) index in theta of each frame's own parameter


def _ls_spec(sample, data, *, eps_min, eps_max_bound, n_segments, p_max, mirror,
             free_ratio=False) -> _Spec:
    """The line-segment model; with ``free_ratio`` each frame's p/p_max is a parameter
    (``ratio_<frame>``, after Δε, k, λ), started at ``data.pressure_mpa / p_max``."""
    m = data.n_fractions
    p = data.pressure_mpa
    abs_de = np.abs(sample.geometry.d_e_um)
    k_lo = -(1.0 - 1e-3) / abs_de.max()  # 1 + k|d_e| > 0 in every section, with a margin
    k_hi = 20.0 / abs_de.max()

    def pressure(theta):
        return theta[:, 3:] * p_max if free_ratio else p

    def params(theta):
        return LSParams(eps_min=eps_min, eps_max=eps_min + theta[:, 0:1],
                        k_de_per_um=theta[:, 1:2], elongation=theta[:, 2:3],
                        n_segments=n_segments, p_max_mpa=p_max)

    def shapes(theta):
        theta = np.atleast_2d(theta)
        sh = ls_shape(sample, pressure(theta), params(theta), n_points=m + 1)
        z = sh.x_um[..., 1:] + 1j * sh.y_um[..., 1:]
        tip = sh.phi_rad[..., -1]
        return (np.conj(z), -tip) if mirror else (z, tip)

    def tips(theta):
        theta = np.atleast_2d(theta)
        tip = ls_bend_angle(sample, pressure(theta), params(theta))
        return -tip if mirror else tip

    names = ("delta_eps", "k_de", "elongation")
    default = [DEFAULT_EPS_MAX - eps_min, 0.0, 1.0]
    lower, upper = [0.0, k_lo, 0.5], [eps_max_bound - eps_min, k_hi, 2.0]
    per_frame = None
    if free_ratio:
        names += tuple(f"ratio_{f}" for f in data.frame)
        default += list(p / p_max)
        lower += [0.0] * data.n_frames
        upper += [RATIO_MAX] * data.n_frames
        per_frame = 3 + np.arange(data.n_frames)
    return _Spec(names=names, default=np.array(default), lower=np.array(lower),
                 upper=np.array(upper), shapes=shapes, tips=tips, per_frame=per_frame)


def _eb_spec(sample, data, *, mirror) -> _Spec:
    m = data.n_fractions
    p = data.pressure_mpa

    def shapes(theta):
        theta = np.atleast_2d(theta)
        sh = eb_shape(sample, p, E_mpa=theta[:, 0:1], n_points=m + 1)
        z = sh.x_um[..., 1:] + 1j * sh.y_um[..., 1:]
        tip = sh.phi_rad[..., -1]
        return (np.conj(z), -tip) if mirror else (z, tip)

    def tips(theta):
        tip = eb_bend_angle(sample, p, E_mpa=np.atleast_2d(theta)[:, 0:1])
        return -tip if mirror else tip

    return _Spec(names=("E_eff_mpa",), default=np.array([sample.E_mpa]),
                 lower=np.array([1e-3]), upper=np.array([1e3]), shapes=shapes, tips=tips)


class _Problem:
    """Residuals and Jacobian of the placed model for a subset of free parameters."""

    def __init__(self, spec: _Spec, data: FitData, free, fixed_values):
        self.spec, self.data = spec, data
        self.free = np.asarray(free, dtype=int)
        self.full = np.array(fixed_values, dtype=float)
        self.rot = np.exp(1j * data.base_angle_rad)[:, None]

    def theta(self, x):
        x = np.atleast_2d(x)
        th = np.broadcast_to(self.full, (x.shape[0], self.full.size)).copy()
        th[:, self.free] = x
        return th

    def placed(self, x):
        """(K, F, M) model points in the image frame, and (K, F) tip angles, rad."""
        z, tip = self.spec.shapes(self.theta(x))
        return self.data.base[:, None] + self.rot * z, tip

    def _residual_batch(self, x):
        z, _ = self.placed(x)
        d = z - self.data.points
        return np.concatenate([d.real.reshape(d.shape[0], -1),
                               d.imag.reshape(d.shape[0], -1)], axis=1)

    def fun(self, x):
        return self._residual_batch(x)[0]

    def frame_columns(self) -> np.ndarray:
        """(F,) column of each frame's own free parameter in x, −1 where none."""
        cols = np.full(self.data.n_frames, -1)
        if self.spec.per_frame is not None:
            where = {j: i for i, j in enumerate(self.free)}
            cols = np.array([where.get(j, -1) for j in self.spec.per_frame])
        return cols

    def jac(self, x):
        lo, hi = self.spec.lower[self.free], self.spec.upper[self.free]
        h = 1e-7 * np.maximum(np.abs(x), np.maximum(np.abs(hi - lo) * 1e-3, 1e-12))
        h = np.where(x + h > hi, -h, h)  # stay inside the bounds (ls_tilts refuses outside)
        cols = self.frame_columns()
        own = cols[cols >= 0]
        shared = np.setdiff1d(np.arange(x.size), own)
        # a frame's own parameter moves only that frame: step them all in one evaluation
        steps = np.zeros((shared.size + (own.size > 0), x.size))
        steps[np.arange(shared.size), shared] = h[shared]
        steps[shared.size:, own] = h[own]
        r = self._residual_batch(np.vstack([x, x + steps]))
        diff = r[1:] - r[0]
        dense = (diff[: shared.size] / h[shared, None]).T
        if not own.size:
            out = np.zeros((r.shape[1], x.size))
            out[:, shared] = dense
            return out
        # one column per frame with 2M non-zeros: sparse, so that the solver's
        # trust-region steps use LSMR instead of an SVD of the whole Jacobian
        n_f, m = self.data.n_frames, self.data.n_fractions
        rows_d, cols_d = np.indices(dense.shape)
        frame_of = np.flatnonzero(cols >= 0)
        rows_o = (np.arange(2)[:, None, None] * n_f * m + frame_of[None, :, None] * m
                  + np.arange(m)[None, None, :])                       # (2, F', M)
        vals_o = diff[-1].reshape(2, n_f, m)[:, frame_of] / h[cols[frame_of]][None, :, None]
        cols_o = np.broadcast_to(cols[frame_of][None, :, None], rows_o.shape)
        return sparse.csr_matrix(
            (np.concatenate([dense.ravel(), vals_o.ravel()]),
             (np.concatenate([rows_d.ravel(), rows_o.ravel()]),
              np.concatenate([shared[cols_d.ravel()], cols_o.ravel()]))),
            shape=(r.shape[1], x.size))


# -- fitting -------------------------------------------------------------------------------


def _soft_l1_weight(r, f_scale):
    """IRLS weight ρ'(z) of the soft-L1 loss, z = (r/f)²."""
    return 1.0 / np.sqrt(1.0 + (r / f_scale) ** 2)


def tracking_patterns(data: FitData, fractions, *, sd_deg: float = TRACKING_SD_DEG,
                      length_sd: float = TRACKING_LENGTH_SD) -> np.ndarray:
    """Perturbations of the measured shapes by the tracker's systematic errors, 1 sd each.

    A tracker's error repeats from frame to frame (it is in how a shape is
    measured, not in the noise of one frame), so no resampling of frames can
    reveal it; it is propagated through the fit instead (a Type-B uncertainty).
    The patterns, independent of each other:

    * the heading error accumulated along each section: a random walk along the
      tube reaching ``sd_deg`` at the tip, section ``i`` carrying
      ``sd_deg·√fraction_i``, growing across the section and carried beyond it,
      scaled in each frame by its bend relative to the most bent frame;
    * a base-tangent error of ``sd_deg`` (the whole shape turned about its base);
    * a length scale error of ``length_sd`` (relative).

    Parameters
    ----------
    data : FitData
    fractions : sequence of float
        The sample's section fractions, base to tip.
    sd_deg : float
        Heading error at the tip, degrees (1 sd).
    length_sd : float
        Relative length error (1 sd).

    Returns
    -------
    (K, 2·F·M) ndarray
        Point displacements, µm, laid out like the residual vector (x then y).
    """
    z = np.concatenate([data.base[:, None], data.points], axis=1)
    rel = z[:, 1:] - data.base[:, None]
    chord = np.diff(z, axis=1)
    m = data.n_fractions
    u_mid = (np.arange(m) + 0.5) / m
    bend = np.abs(data.bend_deg)
    scale = bend / bend.max() if bend.max() > 0 else np.zeros_like(bend)
    sd = np.radians(sd_deg)
    edges = np.concatenate([[0.0], np.cumsum(fractions)])
    pats = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        dphi = sd * np.sqrt(b - a) * np.clip((u_mid - a) / (b - a), 0.0, 1.0)
        pats.append(np.cumsum(1j * chord * dphi, axis=1) * scale[:, None])
    pats.append(1j * rel * sd)
    pats.append(rel * length_sd)
    d = np.asarray(pats)
    return np.concatenate([d.real.reshape(len(pats), -1), d.imag.reshape(len(pats), -1)],
                          axis=1)


def _statistics(problem: _Problem, x, f_scale, n_boot, rng, patterns=None):
    """Covariance, normalised singular values/vectors, a linearised frame bootstrap and
    the parameter shifts from the tracker's systematic error ``patterns``."""
    r = problem.fun(x)
    jac = problem.jac(x)
    if sparse.issparse(jac):
        jac = jac.toarray()
    n_f, m = problem.data.n_frames, problem.data.n_fractions
    # the two components of a point share the point's weight (distance-based)
    dist = np.hypot(r[: n_f * m], r[n_f * m:])
    w = np.tile(_soft_l1_weight(dist, f_scale), 2)
    sw = np.sqrt(w)
    jw, rw = jac * sw[:, None], r * sw
    norms = np.linalg.norm(jw, axis=0)
    norms[norms == 0] = 1.0
    u_, sv, vt = np.linalg.svd(jw / norms, full_matrices=False)
    keep = sv > _RCOND * sv[0]
    dof = max(r.size - x.size, 1)
    s2 = float(rw @ rw) / dof
    cov_n = (vt[keep].T / sv[keep] ** 2) @ vt[keep]
    cov = s2 * cov_n / np.outer(norms, norms)
    # per-frame normal equations (in normalised coordinates) for the bootstrap
    p = x.size
    jn = (jw / norms).reshape(2, n_f, m, p).transpose(1, 0, 2, 3).reshape(n_f, 2 * m, p)
    rn = rw.reshape(2, n_f, m).transpose(1, 0, 2).reshape(n_f, 2 * m)
    a_f = np.einsum("fip,fiq->fpq", jn, jn)
    g_f = np.einsum("fip,fi->fp", jn, rn)
    cols = problem.frame_columns()
    if problem.spec.per_frame is not None and (cols < 0).any():
        # the frame whose own parameter is held (p/p_max = 1) fixes the scale of the
        # others: it is in every replicate, the other frames are resampled
        anchor = cols < 0
        counts = np.zeros((n_boot, n_f))
        counts[:, anchor] = 1.0
        rest = int((~anchor).sum())
        counts[:, ~anchor] = rng.multinomial(rest, np.full(rest, 1.0 / rest), size=n_boot)
    else:
        counts = rng.multinomial(n_f, np.full(n_f, 1.0 / n_f), size=n_boot).astype(float)
    a_b = np.einsum("bf,fpq->bpq", counts, a_f)
    g_b = np.einsum("bf,fp->bp", counts, g_f)
    # rank-cut pseudo-inverse per replicate, relative to the full-data scale
    steps = np.empty((n_boot, p))
    for b in range(n_boot):
        ev, evec = np.linalg.eigh(a_b[b])
        good = ev > (_RCOND * sv[0]) ** 2 * n_f
        steps[b] = -(evec[:, good] / ev[good]) @ (evec[:, good].T @ g_b[b])
    boot = x + steps / norms
    # a displacement δ of the measured points shifts the solution by A⁺ Jᵀ W δ
    # (residual = model − measured); patterns are independent, so shifts add in quadrature
    sys_sd = np.zeros(p)
    if patterns is not None and len(patterns):
        shifts = (cov_n @ ((jw / norms).T @ (patterns * sw).T)).T / norms
        sys_sd = np.sqrt(np.sum(shifts**2, axis=0))
    # identifiability of the shared parameters, with each frame's own parameter (which
    # moves that frame only) projected out of them
    shared = np.setdiff1d(np.arange(p), cols[cols >= 0])
    sv_s, vt_s = sv / sv[0], vt
    if shared.size < p:
        g = jn[:, :, shared].copy()
        for f, c in enumerate(cols):
            if c >= 0:
                cf = jn[f, :, c]
                g[f] -= np.outer(cf, cf @ g[f]) / max(cf @ cf, 1e-300)
        g = g.reshape(-1, shared.size)
        gn = np.linalg.norm(g, axis=0)
        gn[gn == 0] = 1.0
        _, sv_s, vt_s = np.linalg.svd(g / gn, full_matrices=False)
        sv_s = sv_s / sv_s[0]
    return {"cov": cov, "sv": sv / sv[0], "vt": vt, "sv_shared": sv_s, "vt_shared": vt_s,
            "shared": shared, "boot": boot, "sys_sd": sys_sd,
            "residual": r,
            "dist": dist, "weight": w[: n_f * m].reshape(n_f, m)}


def _at_bound(value, lo, hi):
    span = hi - lo
    return value <= lo + 1e-6 * span or value >= hi - 1e-6 * span


def _angle_scan(spec: _Spec, data: FitData, index: int, grid: np.ndarray, base: np.ndarray):
    """The grid value of parameter ``index`` whose tip angles best match the measured ones."""
    th = np.broadcast_to(base, (grid.size, base.size)).copy()
    th[:, index] = grid
    tip = spec.tips(th)
    err = np.abs(np.degrees(tip) - data.bend_deg)
    return float(grid[np.argmin(np.median(err, axis=1))])


def _length_trend(data: FitData, p_ratio: np.ndarray):
    """Fit L = a + b·(p/p_max) robustly: (a, b, stderr of b)."""
    keep = np.ones(data.n_frames, bool)
    for _ in range(3):
        design = np.column_stack([np.ones(keep.sum()), p_ratio[keep]])
        coef, *_ = np.linalg.lstsq(design, data.length_um[keep], rcond=None)
        res = data.length_um - (coef[0] + coef[1] * p_ratio)
        mad = robust_sd(res[keep])
        new = np.abs(res) <= max(5 * mad, 1e-9 * abs(coef[0]))
        if new.sum() < 3 or (new == keep).all():
            break
        keep = new
    design = np.column_stack([np.ones(keep.sum()), p_ratio[keep]])
    coef, *_ = np.linalg.lstsq(design, data.length_um[keep], rcond=None)
    res = data.length_um[keep] - design @ coef
    dof = max(keep.sum() - 2, 1)
    cov = (res @ res / dof) * np.linalg.pinv(design.T @ design)
    return float(coef[0]), float(coef[1]), float(np.sqrt(max(cov[1, 1], 0.0)))


def calibrate(sample, tracks: pd.DataFrame, centrelines: pd.DataFrame, *, pressure_csv=None,
              p_max=None, model: str = "ls", n_segments: int | None = None,
              n_fractions: int = DEFAULT_FRACTIONS, f_scale_um: float | None = None,
              eps_min: float = DEFAULT_EPS_MIN, eps_max_bound: float = DEFAULT_EPS_MAX,
              fit_k: bool | None = None, fit_elongation: bool | None = None,
              initial: dict | None = None, n_bootstrap: int = DEFAULT_BOOTSTRAP,
              tracking_sd_deg: float = TRACKING_SD_DEG, rng=None) -> CalibrationResult:
    """Fit the line-segment (``"ls"``) or Euler–Bernoulli (``"eb"``) model to tracked shapes.

    Parameters
    ----------
    sample : Sample, int or str
        The sample (catalogue id, ``"#1"``, a TOML path or a :class:`Sample`).
    tracks, centrelines : DataFrame
        The tracker's tables (:mod:`pipeline.schema`), lengths in µm, y up.
    pressure_csv : str or Path, optional
        Pressure log (``frame`` or ``time_s``, ``pressure_mpa``).
    p_max : float, optional
        Without a log: pressure ramps linearly from 0 to ``p_max`` MPa over
        the frames. At most one of ``pressure_csv`` and ``p_max``; with neither
        (line-segment model only) each frame's p/p_max is fitted, the most bent
        frame's held at 1 (``pressure_source`` says so).
    model : {"ls", "eb"}
    n_segments : int, optional
        Line segments N of the ls model (default 1000).
    n_fractions : int
        Arc-length fractions M compared per frame (default 100).
    f_scale_um : float, optional
        Soft-L1 scale, µm. Default: 3 × the centreline point spacing (≈ 3 px:
        the tracker writes points ≤ 1 px apart), shrunk once after a first fit
        to 3 × the robust scale of the point distances (at least 1 µm) when that
        is less than half of it.
    eps_min : float
        ε_min, held fixed (default 0.5); ε_max is fitted in ``[eps_min, eps_max_bound]``.
    fit_k, fit_elongation : bool, optional
        Force k / λ free (True) or fixed (False); None decides from the data.
    initial : dict, optional
        Start values by internal name (``delta_eps``, ``k_de``, ``elongation``,
        ``E_eff_mpa``) instead of the angle scan (for multi-start checks).
    n_bootstrap : int
        Bootstrap replicates over frames (default 200).
    tracking_sd_deg : float
        The tracker's systematic heading error at the tip, degrees (1 sd,
        default 0.5): propagated into the intervals (:func:`tracking_patterns`);
        0 leaves only the bootstrap over frames.
    rng : numpy.random.Generator or int, optional
        For the bootstrap (default seed 0: results are reproducible).

    Returns
    -------
    CalibrationResult
        ``residuals`` has one row per used frame: frame, pressure_mpa (fitted
        when the pressures were free), p_over_p_max, rms_um, max_um, weight
        (mean soft-L1 weight), bend_measured_deg, bend_model_deg.

    Raises
    ------
    ValueError
        Unknown sample, bad model or options, a sample length disagreeing with
        the tracks by more than 30%, a pressure log not covering the frames, or
        fewer than two usable frames.
    """
    t_start = time.perf_counter()
    sample = get_sample(sample)
    if model not in ("ls", "eb"):
        raise ValueError(f"model must be 'ls' or 'eb', got {model!r}")
    if model == "eb" and n_segments is not None:
        raise ValueError("n_segments applies to the line-segment model (ls) only")
    if not (isinstance(n_fractions, int) and n_fractions >= 2):
        raise ValueError(f"n_fractions must be a whole number >= 2, got {n_fractions!r}")
    if not (np.isfinite(tracking_sd_deg) and tracking_sd_deg >= 0):
        raise ValueError(f"tracking_sd_deg must be a number >= 0, got {tracking_sd_deg!r}")
    rng = np.random.default_rng(0 if rng is None else rng)
    n_seg = DEFAULT_SEGMENTS if n_segments is None else int(n_segments)
    if model == "ls" and n_seg < sample.n_sections:
        raise ValueError(f"n_segments must be >= the number of sections "
                         f"({sample.n_sections}), got {n_segments!r}")

    frames, skipped = usable_frames(tracks, centrelines)
    if frames.size < 2:
        raise ValueError(f"fewer than two usable frames ({frames.size} of {len(tracks)} ok)")
    free_ratio = pressure_csv is None and p_max is None
    if free_ratio:
        if model != "ls":
            raise ValueError("no pressures: the Euler-Bernoulli model needs them (p and "
                             "E_eff enter only as p/E); give --pressure CSV or --p-max")
        pressures = _free_pressures(tracks, frames, sample)
    else:
        pressures = frame_pressures(tracks, frames, pressure_csv=pressure_csv, p_max=p_max)
    source = pressures.source
    data = prepare_data(tracks, centrelines, pressures, n_fractions=n_fractions)
    median_len = float(np.median(data.length_um))
    if abs(median_len / sample.length_um - 1.0) > LENGTH_TOL:
        raise ValueError(f"sample {sample.name} is {sample.length_um:g} um long but the tracked "
                         f"tube is {median_len:.0f} um (median): wrong sample or scale?")
    patterns = tracking_patterns(data, [sec.fraction for sec in sample.sections],
                                 sd_deg=tracking_sd_deg)
    tighten = f_scale_um is None
    f_scale = float(f_scale_um) if f_scale_um is not None else max(3.0 * data.spacing_um, 1.0)
    if not (np.isfinite(f_scale) and f_scale > 0):
        raise ValueError(f"f_scale_um must be a positive number, got {f_scale_um!r}")

    notes = [f"{n} frame(s) skipped: {why}" for why, n in skipped.items()]
    p_model = None
    if model == "ls":
        p_model = pressures.p_max_mpa or sample.p_max_mpa or float(data.pressure_mpa.max())
        if free_ratio:
            p_model = float(data.pressure_mpa.max())
        if not p_model > 0:
            raise ValueError("cannot set p_max: no --p-max, the sample has none and the "
                             "logged pressures are all 0")
    # mirror the model when the tube is seen from its other side (bends the other way)
    probe = _ls_spec(sample, data, eps_min=eps_min, eps_max_bound=eps_max_bound,
                     n_segments=n_seg, p_max=p_model, mirror=False) if model == "ls" else \
        _eb_spec(sample, data, mirror=False)
    sign_model = np.sign(np.median(probe.tips(probe.default)))
    sign_data = np.sign(np.median(data.bend_deg[data.pressure_mpa > 0])) \
        if (data.pressure_mpa > 0).any() else sign_model
    mirror = bool(sign_model != 0 and sign_data != 0 and sign_model != sign_data)
    if mirror:
        notes.append("the tube bends the other way than the model: model mirrored "
                     "(tube seen from its other side)")

    if model == "ls":
        spec = _ls_spec(sample, data, eps_min=eps_min, eps_max_bound=eps_max_bound,
                        n_segments=n_seg, p_max=p_model, mirror=mirror, free_ratio=free_ratio)
        outcome = _fit_ls(spec, sample, data, f_scale=f_scale, tighten=tighten, fit_k=fit_k,
                          fit_elongation=fit_elongation, initial=initial, p_max=p_model,
                          n_boot=n_bootstrap, rng=rng, eps_min=eps_min, patterns=patterns)
    else:
        spec = _eb_spec(sample, data, mirror=mirror)
        outcome = _fit_eb(spec, sample, data, f_scale=f_scale, tighten=tighten, initial=initial,
                          n_boot=n_bootstrap, rng=rng, patterns=patterns)
    theta, names_out, params, corr, stats, res, extra_notes, f_scale = outcome
    notes.extend(extra_notes)

    z, tip = spec.shapes(theta)
    placed = data.base[:, None] + np.exp(1j * data.base_angle_rad)[:, None] * z[0]
    dist = np.abs(placed - data.points)
    bend_model = np.degrees(tip[0])
    pressure = data.pressure_mpa
    if spec.per_frame is not None:
        pressure = theta[spec.per_frame] * p_model
    table = pd.DataFrame({
        S.FRAME: data.frame, S.PRESSURE: pressure,
        "p_over_p_max": pressure / p_model if p_model else np.nan,
        "rms_um": np.sqrt(np.mean(dist**2, axis=1)), "max_um": dist.max(axis=1),
        "weight": stats["weight"].mean(axis=1),
        "bend_measured_deg": data.bend_deg, "bend_model_deg": bend_model})
    runtime = time.perf_counter() - t_start
    return CalibrationResult(
        model=model, sample=sample.name, parameters=params, correlation=corr,
        rms_um=float(np.sqrt(np.mean(dist**2))), max_residual_um=float(dist.max()),
        angle_rms_deg=float(np.sqrt(np.mean((bend_model - data.bend_deg) ** 2))),
        frames_used=data.n_frames, frames_skipped=int(len(tracks) - data.n_frames),
        pressure_source=source, runtime_s=runtime,
        n_segments=n_seg if model == "ls" else None, p_max_mpa=p_model, residuals=table,
        singular_values=tuple(float(v) for v in stats["sv_shared"]), f_scale_um=f_scale,
        mirrored=mirror, success=bool(res.success), message=str(res.message),
        notes=tuple(notes),
        bootstrap={"replicates": int(n_bootstrap), "method": "frames resampled with "
                   "replacement; one Gauss-Newton step from the solution per replicate",
                   "tracking_sd_deg": float(tracking_sd_deg),
                   "tracking_method": "ci95 widened in quadrature by 1.96 x the parameter "
                   "shift from the tracker's systematic errors (heading random walk per "
                   "section, base tangent, length scale)"},
        _curves={"measured": data.points, "model": placed, "base": data.base,
                 "pressure": pressure, "frame": data.frame})


def _free_pressures(tracks, frames, sample) -> FramePressures:
    """Starting pressures when none are known: p/p_max = |bend| / the largest |bend|.

    The line-segment model's tip angle is exactly proportional to p/p_max (with
    λ = 1), so this is the tip-angle estimate of each frame's ratio; the fit
    then refines every ratio but the most bent frame's (held at 1).
    """
    row = tracks.drop_duplicates(S.FRAME).set_index(S.FRAME).loc[frames]
    bend = np.abs(row[S.BEND].to_numpy(float))
    if not bend.max() > 0:
        raise ValueError("no pressures and no frame bends: cannot estimate p/p_max")
    p_max = sample.p_max_mpa or 1.0
    return FramePressures(
        frame=np.asarray(frames, dtype=np.int64), pressure_mpa=p_max * bend / bend.max(),
        kind="free", p_max_mpa=None,
        source="free: no pressure log or --p-max; each frame's p/p_max fitted (the most "
               "bent frame at 1" + (f", p_max = {p_max:g} MPa from the sample)"
                                    if sample.p_max_mpa else ")"))


def _solve(spec, data, free, start, f_scale, tighten):
    """Robust fit of the ``free`` parameters; with ``tighten``, f_scale may shrink once.

    Returns the problem, SciPy's result and the f_scale of the final solve.
    """
    problem = _Problem(spec, data, free, start)
    lo, hi = spec.lower[free], spec.upper[free]
    x0 = np.clip(start[free], lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
    while True:
        res = least_squares(problem.fun, x0, jac=problem.jac, bounds=(lo, hi), method="trf",
                            loss="soft_l1", f_scale=f_scale, x_scale="jac", xtol=1e-10,
                            ftol=1e-10, gtol=1e-10, max_nfev=200,
                            tr_solver="lsmr" if spec.per_frame is not None else "exact")
        if not tighten:
            return problem, res, f_scale
        # a few times the typical point distance, when that is below the pixel-based scale:
        # then one mistracked frame pulls with a smaller bounded influence
        n = data.n_frames * data.n_fractions
        sigma = 1.4826 * float(np.median(np.hypot(res.fun[:n], res.fun[n:])))
        tighter = max(3.0 * sigma, 1.0)
        if tighter >= 0.5 * f_scale:
            return problem, res, f_scale
        f_scale, x0, tighten = tighter, res.x, False


def _fit_ls(spec, sample, data, *, f_scale, tighten, fit_k, fit_elongation, initial, p_max,
            n_boot, rng, eps_min, patterns):
    notes = []
    reasons = {}
    ratio = data.pressure_mpa / p_max
    start = spec.default.copy()
    # λ: only when the measured length changes with the pressure
    a, b, se_b = _length_trend(data, ratio)
    change = b * float(ratio.max()) / a
    if fit_elongation is None:
        fit_elongation = abs(b) > 3 * se_b and abs(change) > ELONGATION_MIN_CHANGE
    if fit_elongation:
        start[2] = float(np.clip(1.0 + b / a, spec.lower[2] + 1e-6, spec.upper[2] - 1e-6))
    else:
        noise = 300 * se_b / a * ratio.max()  # 3 stderr, % of the length
        reasons["elongation"] = (f"the measured length does not change with pressure beyond "
                                 f"noise ({100 * change:+.2f}% +- {noise:.2f}% over the "
                                 f"pressure range): fixed at 1")
    # k: only with sections that differ in |d_e|
    abs_de = np.abs(sample.geometry.d_e_um)
    if fit_k is None:
        fit_k = sample.n_sections > 1 and np.ptp(abs_de) > 0
    if not fit_k:
        reasons["k_de"] = ("one section: k only rescales the tilt like delta_eps; fixed at 0"
                           if sample.n_sections == 1 else
                           "sections have the same |d_e|: k only rescales the tilt like "
                           "delta_eps; fixed at 0")
    free = [0] + ([1] if fit_k else []) + ([2] if fit_elongation else [])
    if spec.per_frame is not None:
        # each frame's p/p_max is free but for the most bent frame's, held at 1: the
        # tilt is (function of Δε) × p/p_max, so one ratio must be fixed to tell Δε
        ref = int(np.argmax(np.abs(data.bend_deg)))
        free += [int(j) for f, j in enumerate(spec.per_frame) if f != ref]
        notes.append(f"pressures unknown: each frame's p/p_max fitted, frame "
                     f"{int(data.frame[ref])} (the most bent) taken at p_max; Δε is then "
                     f"the strain range that bends the tube that far")
    # start: 1-D scan of Δε on the tip angles
    grid = np.geomspace(1e-4, spec.upper[0], 400)
    start[0] = _angle_scan(spec, data, 0, grid, start)
    if initial:
        for key, val in initial.items():
            start[spec.names.index(key)] = float(val)
    while True:
        problem, res, f_used = _solve(spec, data, free, start, f_scale, tighten)
        stats = _statistics(problem, res.x, f_used, n_boot, rng, patterns)
        # positions in x of k and λ (the shared parameters come first in x)
        droppable = [i for i, j in enumerate(free) if j in (1, 2)]
        if stats["sv_shared"][-1] < NULL_TOL and droppable:
            v = np.abs(stats["vt_shared"][-1])
            drop = max(droppable, key=lambda i: v[i])
            j = free[drop]
            corr = _corr(stats["cov"])
            other = [free[i] for i in range(len(free)) if i != drop]
            rho = max((abs(corr[drop, i]) for i in range(len(free))
                       if i != drop and free[i] < 3), default=0)
            reasons[spec.names[j]] = (
                f"not determined: near-null direction of the Jacobian (normalised singular "
                f"value {stats['sv_shared'][-1]:.2g} < {NULL_TOL}; |correlation| {rho:.4f} "
                f"with {', '.join(_out_name(spec.names[o]) for o in other if o < 3)})"
                + (f"; sections differ in |d_e| by only {np.ptp(abs_de):.1f} um"
                   if j == 1 else "") + f"; fixed at {spec.default[j]:g}")
            start = spec.default.copy()
            start[[f for f in free if f != j]] = res.x[[i for i in range(len(free)) if i != drop]]
            free = [f for f in free if f != j]
            continue
        break
    theta = problem.theta(res.x)[0]
    names = [_out_name(n) for n in spec.names]
    fitted_vals = dict(zip([spec.names[j] for j in free], range(len(free)), strict=True))
    params = {"eps_min": ParameterEstimate(
        eps_min, fitted=False,
        reason="eps_min and eps_max enter the model only through delta_eps = eps_max - "
               f"eps_min: eps_min is held at {eps_min:g} and eps_max carries the fit")}
    for j, name in enumerate(spec.names[:3]):
        offset = eps_min if j == 0 else 0.0
        if name not in fitted_vals:
            params[names[j]] = ParameterEstimate(float(theta[j] + offset), fitted=False,
                                                 reason=reasons.get(name, "fixed"))
            continue
        i = fitted_vals[name]
        params[names[j]] = _estimate(res.x[i], stats, i, spec.lower[j], spec.upper[j], offset)
    corr = _corr(stats["cov"])
    cnames = [(i, names[j]) for i, j in enumerate(free) if j < 3]
    correlation = {a: {b: float(corr[i, k]) for k, b in cnames} for i, a in cnames}
    return theta, names, params, correlation, stats, res, notes, f_used


def _fit_eb(spec, sample, data, *, f_scale, tighten, initial, n_boot, rng, patterns):
    start = spec.default.copy()
    grid = np.geomspace(spec.lower[0] * 10, spec.upper[0] / 10, 400)
    start[0] = _angle_scan(spec, data, 0, grid, start)
    if initial:
        start[0] = float(initial.get("E_eff_mpa", start[0]))
    problem, res, f_used = _solve(spec, data, [0], start, f_scale, tighten)
    stats = _statistics(problem, res.x, f_used, n_boot, rng, patterns)
    params = {"E_eff_mpa": _estimate(res.x[0], stats, 0, spec.lower[0], spec.upper[0], 0.0)}
    correlation = {"E_eff_mpa": {"E_eff_mpa": 1.0}}
    return (problem.theta(res.x)[0], ["E_eff_mpa"], params, correlation, stats, res, [],
            f_used)


def _estimate(x, stats, i, lo, hi, offset) -> ParameterEstimate:
    se = float(np.sqrt(max(stats["cov"][i, i], 0.0)))
    boot = np.clip(stats["boot"][:, i], lo, hi)
    b_lo, b_hi = np.percentile(boot, [2.5, 97.5])
    sys_sd = float(stats["sys_sd"][i])
    # frame-to-frame scatter (bootstrap) and tracker bias (Type B) are independent
    half_lo = np.hypot(max(x - b_lo, 0.0), 1.96 * sys_sd)
    half_hi = np.hypot(max(b_hi - x, 0.0), 1.96 * sys_sd)
    ci = (float(max(x - half_lo, lo) + offset), float(min(x + half_hi, hi) + offset))
    if _at_bound(x, lo, hi):
        return ParameterEstimate(float(x + offset), se, ci, fitted=False,
                                 reason=f"not determined: at its bound [{lo + offset:g}, "
                                        f"{hi + offset:g}]", tracking_sd=sys_sd)
    return ParameterEstimate(float(x + offset), se, ci, fitted=True, tracking_sd=sys_sd)


def _corr(cov):
    d = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    return np.clip(cov / np.outer(d, d), -1.0, 1.0)


def _out_name(internal: str) -> str:
    return "eps_max" if internal == "delta_eps" else internal


# -- files -------------------------------------------------------------------------------


def calibrate_folder(sample, tracks_dir, *, pressure_csv=None, p_max=None, model: str = "ls",
                     n_segments: int | None = None, out_json, **options) -> CalibrationResult:
    """Calibrate on a tracker output folder and write the JSON, residual CSV and overlay PNG.

    Parameters
    ----------
    sample : Sample, int or str
        Catalogue id (1–8), ``"#1"`` or a sample TOML path.
    tracks_dir : str or Path
        Folder with ``tracks.csv`` and ``centrelines.csv``. Without
        ``pressure_csv`` and ``p_max``, a ``pressure.csv`` in this folder is used;
        without that either, each frame's p/p_max is fitted (ls model).
    pressure_csv, p_max, model, n_segments
        As for :func:`calibrate`.
    out_json : str or Path
        Result JSON; ``<stem>_residuals.csv`` and ``<stem>_overlay.png`` are
        written beside it. All three are written atomically.
    **options
        Passed on to :func:`calibrate`.

    Returns
    -------
    CalibrationResult
    """
    if pressure_csv is not None and p_max is not None:
        raise ValueError("give either a pressure log (--pressure) or --p-max, not both")
    sample = get_sample(sample)
    tracks, centrelines = read_tracks(tracks_dir)
    if pressure_csv is None and p_max is None:
        beside = Path(tracks_dir) / S.PRESSURE_FILE
        if beside.is_file():
            pressure_csv = beside
    result = calibrate(sample, tracks, centrelines, pressure_csv=pressure_csv, p_max=p_max,
                       model=model, n_segments=n_segments, **options)
    write_result(result, out_json)
    return result


def write_result(result: CalibrationResult, out_json) -> dict[str, Path]:
    """Write the JSON, ``<stem>_residuals.csv`` and ``<stem>_overlay.png`` (atomically)."""
    out_json = Path(out_json)
    if not out_json.parent.is_dir():
        raise ValueError(f"output folder does not exist: {out_json.parent}")
    paths = {"json": out_json,
             "residuals": out_json.with_name(f"{out_json.stem}_residuals.csv"),
             "overlay": out_json.with_name(f"{out_json.stem}_overlay.png")}
    # all three are made first and moved into place together (the JSON last): a
    # failure on the way leaves none of them behind
    with contextlib.ExitStack() as stack:
        tmp = {key: stack.enter_context(atomic_path(path))
               for key, path in (("json", paths["json"]), ("overlay", paths["overlay"]),
                                 ("residuals", paths["residuals"]))}
        write_csv(result.residuals, tmp["residuals"], float_format="%.6g")
        write_overlay(result, tmp["overlay"])
        write_json(result.to_dict(), tmp["json"])
    return paths


def write_overlay(result: CalibrationResult, path, *, n_shapes: int = 6) -> Path:
    """Model (dashed) on measured (solid) centrelines at up to ``n_shapes`` pressures."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    c = result._curves
    order = np.argsort(c["pressure"], kind="stable")
    pick = order[np.unique(np.linspace(0, order.size - 1, min(n_shapes, order.size))
                           .round().astype(int))]
    fig = Figure(figsize=(6.4, 5.6), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    colours = [f"C{i % 10}" for i in range(pick.size)]
    for colour, i in zip(colours, pick, strict=True):
        meas = np.concatenate([[c["base"][i]], c["measured"][i]])
        mod = np.concatenate([[c["base"][i]], c["model"][i]])
        ax.plot(meas.real, meas.imag, "-", color=colour, lw=2.0, alpha=0.55,
                label=f"frame {c['frame'][i]}, {c['pressure'][i]:.3g} MPa")
        ax.plot(mod.real, mod.imag, "--", color=colour, lw=1.2)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (µm)")
    ax.set_ylabel("y (µm)")
    ax.set_title(f"sample {result.sample}, {result.model} model: measured (solid), "
                 f"model (dashed)\nrms {result.rms_um:.1f} µm", fontsize=9)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    return Path(path)


def _num(v):
    """A float for JSON (None for missing or non-finite)."""
    if v is None:
        return None
    v = float(v)
    return v if np.isfinite(v) else None


__all__ = ["CalibrationResult", "FitData", "ParameterEstimate", "calibrate",
           "calibrate_folder", "prepare_data", "read_tracks", "tracking_patterns", "usable_frames",
           "write_overlay", "write_result"]
