"""Numbers of robot programs written again in their own style (kincal._numstyle): every number of the real
programs in ``../shared/datasets/robot_programs`` reads back as the same text, and new values keep each field's
sign, leading zero, padding, point, decimals and exponent (values checked against their text by float())."""
import re

import pytest

from kincal._numstyle import MAX_DECIMALS, Style, restyle

from conftest import shared_dataset

PROGRAMS = shared_dataset("robot_programs")
NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])")


def test_every_number_of_the_real_programs_is_written_back_as_it_was():
    count = 0
    for path in sorted(p for p in PROGRAMS.rglob("*") if p.is_file() and p.suffix.lower() not in (".csv", ".md")):
        for m in NUMBER.finditer(path.read_bytes().decode("latin-1")):
            assert restyle(m.group(), float(m.group()), 1e-9) == m.group(), (path.name, m.group())
            count += 1
    assert count > 15_000  # the folder's 185 programs hold about 20,000 numbers


@pytest.mark.parametrize("old, value, new", [
    ("-.242", -0.5, "-.500"),  # no leading zero, three decimals
    ("-.242", -1.25, "-1.250"),  # a whole part where one is needed
    ("90", -90.0123, "-90.0123"),  # decimals only as many as the value needs
    ("9E9", 9e9, "9E9"), ("9E+09", 9e9, "9E+09"),  # the same exponent, as written
    ("1.5e-3", 0.00151, "1.51e-3"),
    ("+5.0", 5.25, "+5.25"), ("90.", 91.0, "91."),
    ("05", 7.0, "07"), ("10", 9.99, "9.99"),  # zero-padded stays padded; "10" was not padded
    ("0.000", -1e-12, "0.000"), ("-0.0", 0.0, "0.0"), ("-0", -0.0, "-0"),
])
def test_new_values_keep_their_fields_style(old, value, new):
    assert restyle(old, value, 1e-6) == new
    assert abs(float(new) - value) <= 1e-6


def test_a_value_finer_than_the_decimals_gets_just_the_decimals_it_needs():
    text, decimals = Style.of("12.5").write(12.123456789, 1e-7)
    assert text == "12.1234568" and decimals == 7
    assert len(Style.of("1.0").write(1 / 3, 1e-30)[0].split(".")[1]) == MAX_DECIMALS


@pytest.mark.parametrize("bad", ["", "abc", "1.2.3", "e5", "."])
def test_what_is_not_a_number_is_refused(bad):
    with pytest.raises(ValueError, match="is not a number"):
        Style.of(bad)
    with pytest.raises(ValueError, match="cannot be written"):
        Style.of("1.0").write(float("nan"), 1e-6)


def test_many_numbers_at_once_are_written_as_one_by_one():
    """restyle_all (the writers' batched form) against restyle, number by number: every number of the real
    programs moved by a random amount at three resolutions, and exact round trips."""
    import numpy as np

    from kincal._numstyle import restyle_all

    olds = [m.group() for path in sorted(p for p in PROGRAMS.rglob("*") if p.is_file()
                                         and p.suffix.lower() not in (".csv", ".md"))
            for m in NUMBER.finditer(path.read_bytes().decode("latin-1"))]
    rng = np.random.default_rng(3)
    values = np.array([float(o) for o in olds])
    for moved, res in ((values, 1e-9), (values + rng.normal(0, 1e-3, values.size), 1e-7),
                       (values * (1 + rng.normal(0, 1e-6, values.size)), 1e-10)):
        resolution = np.full(values.size, res)
        one_by_one = [restyle(o, float(v), res) for o, v in zip(olds, moved)]
        assert restyle_all(olds, moved, resolution) == one_by_one
    with pytest.raises(ValueError):
        restyle_all(["1.0", "x"], np.array([1.0, 2.0]), np.array([1e-7, 1e-7]))  # the culprit, one by one
