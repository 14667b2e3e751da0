import pytest

from models import PAPER_SAMPLES, Sample, Section, get_sample, load_sample_toml

TOML = """
name = "demo tube"
length_mm = 10.0
template_diameter_um = 470
p_max_mpa = 0.15
[[sections]]
fraction = 0.6
t_top_um = 134
t_bot_um = 67
[[sections]]
fraction = 0.4
t_top_um = 166
t_bot_um = 72
"""


def test_catalogue_holds_table1():
    assert sorted(PAPER_SAMPLES) == list(range(1, 9))
    s1 = PAPER_SAMPLES[1]
    assert s1.length_um == pytest.approx(12290.0)
    assert s1.r_in_um == 235.0 and PAPER_SAMPLES[6].r_in_um == 125.0
    assert s1.n_sections == 4 and PAPER_SAMPLES[8].n_sections == 1
    assert [s.t_top_um for s in s1.sections] == [134, 166, 211, 139]
    assert PAPER_SAMPLES[3].p_max_mpa == 0.17
    for sample in PAPER_SAMPLES.values():
        assert sample.fractions.sum() == pytest.approx(1.0, abs=1e-15)
        assert sample.section_lengths_um.sum() == pytest.approx(sample.length_um, rel=1e-15)


@pytest.mark.parametrize("spec", [2, "2", "#2", " 2 "])
def test_get_sample_by_id(spec):
    assert get_sample(spec) is PAPER_SAMPLES[2]


def test_toml_sample_round_trip(tmp_path):
    path = tmp_path / "tube.toml"
    path.write_text(TOML)
    sample = get_sample(str(path))
    assert sample == load_sample_toml(path)
    assert sample.name == "demo tube"
    assert sample.length_um == pytest.approx(10000.0)
    assert sample.r_in_um == 235.0
    assert sample.E_mpa == 1.4 and sample.p_max_mpa == 0.15
    assert sample.sections[1] == Section(0.4, 166, 72)


@pytest.mark.parametrize("edit,match", [
    (("fraction = 0.4", "fraction = 0.3"), "sum to 1"),
    (("t_bot_um = 72", "t_bot_um = -72"), "t_bot_um"),
    (("t_bot_um = 72", "t_bot_um = nan"), "t_bot_um"),
    (("length_mm = 10.0", "length_mm = 0.0"), "length_um"),
    (("p_max_mpa = 0.15", "p_max_mpa = 0.15\ncolour = 'red'"), "colour"),
    (("t_bot_um = 72", "t_bottom_um = 72"), "sections\\[1\\]"),
    (("name = ", "name == "), "not valid TOML"),
])
def test_bad_toml_names_the_problem(tmp_path, edit, match):
    path = tmp_path / "bad.toml"
    path.write_text(TOML.replace(*edit))
    with pytest.raises(ValueError, match=match) as err:
        load_sample_toml(path)
    assert str(path) in str(err.value)  # which file, too


def test_missing_file_and_unknown_id():
    with pytest.raises(ValueError, match="not found"):
        get_sample("no_such_file.toml")
    with pytest.raises(ValueError, match="unknown sample '9'"):
        get_sample(9)


@pytest.mark.parametrize("kwargs,match", [
    ({"length_um": -1.0}, "length_um"),
    ({"r_in_um": 0.0}, "r_in_um"),
    ({"E_mpa": float("inf")}, "E_mpa"),
    ({"sections": ()}, "at least one"),
    ({"sections": (Section(0.5, 100, 50),)}, "sum to 1"),
])
def test_sample_validation(kwargs, match):
    base = {"name": "x", "length_um": 9000.0, "r_in_um": 235.0,
            "sections": (Section(1.0, 100, 50),)}
    base.update(kwargs)
    with pytest.raises(ValueError, match=match):
        Sample(**base)


def test_section_rejects_bad_fraction():
    with pytest.raises(ValueError, match="fraction"):
        Section(0.0, 100, 50)
    with pytest.raises(ValueError, match="fraction"):
        Section(1.5, 100, 50)


def test_fractions_within_tolerance_are_renormalised():
    s = Sample("x", 1000.0, 100.0, (Section(0.5, 60, 50), Section(0.5 + 5e-7, 70, 50)))
    assert s.fractions.sum() == pytest.approx(1.0, abs=1e-15)
    assert s.section_lengths_um.sum() == pytest.approx(1000.0, rel=1e-15)
