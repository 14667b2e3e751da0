"""Microtube sample descriptions and the paper's Table 1 catalogue.

A :class:`Sample` is immutable: free length, template (void) radius, Young's
modulus and one or more :class:`Section` s, each with a fractional length and top
and bottom wall thicknesses. Any number of sections is allowed.

The catalogue holds the paper's samples #1–#8 (Table 1). The paper gives the
*template diameter* per group of samples but not per sample; we read it as
470 µm for #1–#5 and 250 µm for #6–#8 (r_in = 235 µm and 125 µm). The maximum
pressures 0.14, 0.14 and 0.17 MPa of samples #1–#3 are from §3; the other
samples have none recorded.

User samples come from a TOML file with the same fields::

    name = "my tube"
    length_um = 10000.0          # free length L_tot (or length_mm)
    r_in_um = 235.0              # void radius (or template_diameter_um)
    E_mpa = 1.4                  # optional, default 1.4
    p_max_mpa = 0.15             # optional
    [[sections]]
    fraction = 0.6
    t_top_um = 134.0
    t_bot_um = 67.0
    [[sections]]
    fraction = 0.4
    t_top_um = 166.0
    t_bot_um = 72.0
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from . import _validate
from .section import CrossSection, cross_section

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

#: Young's modulus of Sylgard 184 PDMS assumed by the paper, MPa.
DEFAULT_E_MPA = 1.4
_FRACTION_TOLERANCE = 1e-6


@dataclass(frozen=True)
class Section:
    """One axial section of a microtube.

    Parameters
    ----------
    fraction : float
        Fractional length L_i / L_tot, in (0, 1].
    t_top_um, t_bot_um : float
        Top and bottom wall thicknesses, µm.
    """

    fraction: float
    t_top_um: float
    t_bot_um: float

    def __post_init__(self):
        frac = float(_validate.positive("section fraction", self.fraction))
        if frac > 1 + _FRACTION_TOLERANCE:
            raise ValueError(f"section fraction must be <= 1, got {frac!r}")
        object.__setattr__(self, "fraction", frac)
        object.__setattr__(self, "t_top_um", float(_validate.positive("t_top_um", self.t_top_um)))
        object.__setattr__(self, "t_bot_um", float(_validate.positive("t_bot_um", self.t_bot_um)))


@dataclass(frozen=True)
class Sample:
    """An immutable microtube description.

    Parameters
    ----------
    name : str
        Label used in reports.
    length_um : float
        Free length L_tot (from the pipette to the sealed tip), µm.
    r_in_um : float
        Template (void) radius r_in, µm.
    sections : tuple of Section
        Sections from base to tip; their fractions must sum to 1 within 1e-6
        (they are then renormalised to sum to exactly 1).
    E_mpa : float, optional
        Young's modulus, MPa (default 1.4).
    p_max_mpa : float or None, optional
        Pressure of maximum bending, MPa, if known (used as the line-segment
        model's default p_max).
    """

    name: str
    length_um: float
    r_in_um: float
    sections: tuple[Section, ...]
    E_mpa: float = DEFAULT_E_MPA
    p_max_mpa: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "length_um",
                           float(_validate.positive("length_um", self.length_um)))
        object.__setattr__(self, "r_in_um", float(_validate.positive("r_in_um", self.r_in_um)))
        object.__setattr__(self, "E_mpa", float(_validate.positive("E_mpa", self.E_mpa)))
        if self.p_max_mpa is not None:
            object.__setattr__(
                self, "p_max_mpa", float(_validate.positive("p_max_mpa", self.p_max_mpa))
            )
        sections = tuple(self.sections)
        if not sections:
            raise ValueError("sections must hold at least one section, got none")
        for sec in sections:
            if not isinstance(sec, Section):
                raise ValueError(f"sections must be Section objects, got {sec!r}")
        total = sum(sec.fraction for sec in sections)
        if abs(total - 1.0) > _FRACTION_TOLERANCE:
            raise ValueError(f"section fractions must sum to 1 (within 1e-6), got {total!r}")
        object.__setattr__(self, "sections", sections)

    # Derived arrays are cached: the dataclass is frozen, so they never go stale
    # (cached_property writes to __dict__ directly, which frozen does not block).
    @cached_property
    def fractions(self) -> np.ndarray:
        """Section fractions renormalised to sum to exactly 1, shape (n_sections,)."""
        f = np.array([s.fraction for s in self.sections])
        return f / f.sum()

    @cached_property
    def section_lengths_um(self) -> np.ndarray:
        """Section lengths L_i, µm, shape (n_sections,)."""
        return self.fractions * self.length_um

    @cached_property
    def section_starts_um(self) -> np.ndarray:
        """Arc length at which each section starts, µm, shape (n_sections,)."""
        starts = np.concatenate([[0.0], np.cumsum(self.section_lengths_um)[:-1]])
        return starts

    @cached_property
    def t_top_um(self) -> np.ndarray:
        """Top wall thickness per section, µm."""
        return np.array([s.t_top_um for s in self.sections])

    @cached_property
    def t_bot_um(self) -> np.ndarray:
        """Bottom wall thickness per section, µm."""
        return np.array([s.t_bot_um for s in self.sections])

    @cached_property
    def geometry(self) -> CrossSection:
        """Cross-section (area, d_e, I) of every section."""
        return cross_section(self.r_in_um, self.t_top_um, self.t_bot_um)

    @cached_property
    def model_cache(self) -> dict:
        """Per-sample constants of the model evaluators, keyed by what they depend on.

        The models keep their per-sample, per-resolution layouts here (segment
        counts, query indices, table layouts) instead of in a global
        ``lru_cache``: looking them up then needs no hash of the whole sample
        (which hashes every section), and they live and die with the sample.
        Internal: the values are read-only arrays owned by :mod:`models`.
        """
        return {}

    @property
    def n_sections(self) -> int:
        return len(self.sections)

    @property
    def outer_radius_um(self) -> np.ndarray:
        """Mean outer radius r_in + (t_t + t_b)/2 per section, µm."""
        return self.r_in_um + 0.5 * (self.t_top_um + self.t_bot_um)

    def with_modulus(self, E_mpa: float) -> Sample:
        """A copy with another Young's modulus."""
        return Sample(self.name, self.length_um, self.r_in_um, self.sections, E_mpa, self.p_max_mpa)


#: Entries kept in one sample's :attr:`Sample.model_cache` (layouts and query
#: indices for different N and point counts); beyond it the cache starts afresh.
_CACHE_ENTRIES = 64


def cached_on(sample: Sample, key, build):
    """``build()``, memoised in ``sample.model_cache`` under ``key`` (internal to models)."""
    cache = sample.model_cache
    value = cache.get(key)
    if value is None:
        value = build()
        if len(cache) >= _CACHE_ENTRIES:  # e.g. a long scan over many N: start afresh
            cache.clear()
        cache[key] = value
    return value


def _paper_sample(num, diameter, length_mm, fractions, tops, bots, p_max=None) -> Sample:
    return Sample(
        name=f"#{num}",
        length_um=length_mm * 1000.0,
        r_in_um=diameter / 2.0,
        sections=tuple(Section(f, t, b) for f, t, b in zip(fractions, tops, bots, strict=True)),
        E_mpa=DEFAULT_E_MPA,
        p_max_mpa=p_max,
    )


#: The paper's Table 1 (template diameters read as 470 µm for #1–#5, 250 µm for #6–#8).
PAPER_SAMPLES: dict[int, Sample] = {
    1: _paper_sample(1, 470, 12.29, [0.43, 0.24, 0.23, 0.10], [134, 166, 211, 139],
                     [67, 72, 67, 67], 0.14),
    2: _paper_sample(2, 470, 8.38, [0.33, 0.36, 0.31], [200, 113, 185], [140, 67, 62], 0.14),
    3: _paper_sample(3, 470, 8.78, [0.61, 0.39], [129, 113], [72, 62], 0.17),
    4: _paper_sample(4, 470, 12.06, [0.17, 0.41, 0.42], [164, 250, 123], [72, 72, 72]),
    5: _paper_sample(5, 470, 9.17, [0.60, 0.30, 0.10], [126, 142, 80], [100, 59, 67]),
    6: _paper_sample(6, 250, 9.57, [0.17, 0.83], [101, 167], [38, 38]),
    7: _paper_sample(7, 250, 8.88, [0.75, 0.13, 0.12], [92, 123, 82], [51, 82, 51]),
    8: _paper_sample(8, 250, 8.80, [1.00], [63], [42]),
}

#: Maximum bending angles of Table 2, degrees: (experiment, paper EB, paper LS).
PAPER_TABLE2: dict[int, dict[str, float]] = {
    1: {"pressure_mpa": 0.14, "experiment_deg": 306.4, "eb_deg": 332.7, "ls_deg": 292.7},
    2: {"pressure_mpa": 0.14, "experiment_deg": 175.7, "eb_deg": 180.8, "ls_deg": 198.2},
    3: {"pressure_mpa": 0.17, "experiment_deg": 273.2, "eb_deg": 243.8, "ls_deg": 283.1},
}

_TOML_KEYS = {"name", "length_um", "length_mm", "r_in_um", "template_diameter_um", "E_mpa",
              "p_max_mpa", "sections"}
_SECTION_KEYS = {"fraction", "t_top_um", "t_bot_um"}


def sample_from_dict(data: dict, *, default_name: str = "sample") -> Sample:
    """Build a :class:`Sample` from a mapping with the TOML file's fields.

    Raises
    ------
    ValueError
        On unknown, missing, duplicated or invalid fields (naming the field).
    """
    unknown = set(data) - _TOML_KEYS
    if unknown:
        raise ValueError(f"unknown sample field(s): {', '.join(sorted(unknown))}")
    if ("length_um" in data) == ("length_mm" in data):
        raise ValueError("give exactly one of length_um or length_mm")
    if ("r_in_um" in data) == ("template_diameter_um" in data):
        raise ValueError("give exactly one of r_in_um or template_diameter_um")
    length = data["length_um"] if "length_um" in data else _mm_to_um(data["length_mm"])
    r_in = data["r_in_um"] if "r_in_um" in data else _half(data["template_diameter_um"])
    raw_sections = data.get("sections")
    if not isinstance(raw_sections, list) or not raw_sections:
        raise ValueError("sections must be a non-empty list of [[sections]] tables")
    sections = []
    for i, sec in enumerate(raw_sections):
        if not isinstance(sec, dict):
            raise ValueError(f"sections[{i}] must be a table, got {sec!r}")
        missing = _SECTION_KEYS - set(sec)
        extra = set(sec) - _SECTION_KEYS
        if missing or extra:
            raise ValueError(
                f"sections[{i}] needs exactly fraction, t_top_um, t_bot_um"
                + (f"; missing {', '.join(sorted(missing))}" if missing else "")
                + (f"; unknown {', '.join(sorted(extra))}" if extra else "")
            )
        sections.append(Section(sec["fraction"], sec["t_top_um"], sec["t_bot_um"]))
    return Sample(
        name=str(data.get("name", default_name)),
        length_um=length,
        r_in_um=r_in,
        sections=tuple(sections),
        E_mpa=data.get("E_mpa", DEFAULT_E_MPA),
        p_max_mpa=data.get("p_max_mpa"),
    )


def _mm_to_um(value):
    return _validate.finite("length_mm", value) * 1000.0


def _half(value):
    return _validate.finite("template_diameter_um", value) / 2.0


def load_sample_toml(path) -> Sample:
    """Read a user sample from a TOML file (fields as in the module docstring)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"sample file not found: {path}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"cannot read sample file {path}: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"sample file {path} is not valid TOML: {exc}") from None
    try:
        return sample_from_dict(data, default_name=path.stem)
    except ValueError as exc:
        # (the fields' checks name the field; the file is named here)
        raise ValueError(f"sample file {path}: {exc}") from None


def get_sample(spec) -> Sample:
    """A catalogue sample by id (``1``, ``"1"``, ``"#1"``) or a sample TOML path."""
    if isinstance(spec, Sample):
        return spec
    text = str(spec).strip()
    key = text.lstrip("#")
    if key.isdigit():
        num = int(key)
        if num not in PAPER_SAMPLES:
            known = ", ".join(str(k) for k in PAPER_SAMPLES)
            raise ValueError(f"unknown sample {text!r}: the catalogue has {known}")
        return PAPER_SAMPLES[num]
    if text.endswith(".toml") or Path(text).exists():
        return load_sample_toml(text)
    raise ValueError(f"unknown sample {text!r}: give a catalogue id (1-8) or a .toml file")
