"""How spreadsheets write numbers: thousands separators, units in cells, emptied rows; the measurement reader and
the compensation targets' reader (``_csv.Table``, ``_csv.Stream``) read and refuse them alike."""
import csv

import numpy as np
import pytest
from conftest import DATA, UR5_COLS

import kincal
from kincal import MeasurementError
from kincal._csv import open_stream

POSITIONS = ["x", "y", "z", "x_target", "y_target", "z_target"]


def _grid():
    """The UR5 grid set's header and rows as written (strings), and its joints (deg) and positions (µm) as floats."""
    rows = list(csv.reader(open(DATA / "ur5_grid.csv", newline="")))
    head, body = rows[0], rows[1:]
    at = [head.index(c) for c in UR5_COLS], [head.index(c) for c in "xyz"]
    values = np.array([[float(c) for c in r] for r in body])
    return head, body, values[:, at[0]], values[:, at[1]] * 1000


def _export(sep, dec, thousands, digits):
    """The grid set as a spreadsheet exports it: positions in µm with ``digits`` decimals and ``thousands`` grouping
    their digits ('' none), decimals written with ``dec``, cells separated by ``sep``."""
    head, body, _, _ = _grid()
    lines = [sep.join(head)]
    for r in body:
        cells = []
        for h, c in zip(head, r):
            if h in POSITIONS:
                c = f"{float(c) * 1000:,.{digits}f}".replace(",", "T").replace(".", "D")
                c = c.replace("T", thousands).replace("D", dec)
                c = f'"{c}"' if sep in c else c  # (as csv writes it)
            else:
                c = c.replace(".", dec)
            cells.append(c)
        lines.append(sep.join(cells))
    return "\n".join(lines) + "\n"


def _read(path):
    return kincal.read_measurements(path, kincal.load_robot("ur5"), joint_cols=UR5_COLS, length_unit="um",
                                    angle_unit="deg")


def _stream(path, cols):
    stream = open_stream(str(path))
    return np.concatenate([stream.numbers(b, cols, "um")[1] for b, _ in stream.blocks()]) * 1e6  # µm


@pytest.mark.parametrize("sep,dec,thousands,example,decimals", [
    (";", ",", ".", "-432.472", "commas (row 2, column 'joint_1': '-22,933297')"),
    ("\t", ".", ",", "-432,472", "points (row 2, column 'joint_1': '-22.933297')")])
def test_a_column_of_whole_numbers_grouped_by_thousands_is_refused_by_both_readers(tmp_path, sep, dec, thousands,
                                                                                   example, decimals):
    """German Excel writes whole µm as '-432.472' beside joints '-22,933297' (US: '-432,472' beside '-22.933297'):
    read cell by cell the positions were 1000 times too small (then 'they look like mm'), values under 1000 ('868')
    right: the column is refused, naming it, a cell and the file's decimals."""
    path = tmp_path / "grid.csv"
    path.write_text(_export(sep, dec, thousands, 0))
    with pytest.raises(MeasurementError, match=f"grid.csv: column 'x' groups thousands with '{thousands}'") as err:
        _read(path)
    for words in (f"(row 2: '{example}'", f"the file's decimals are {decimals}", "-432472 or -432.472",
                  "without thousands separators"):
        assert words in str(err.value)
    with pytest.raises(MeasurementError, match=f"column 'x' groups thousands with '{thousands}'"):
        _stream(path, POSITIONS[:3])


@pytest.mark.parametrize("sep,dec,digits", [(";", ",", 3), ("\t", ",", 3), ("\t", ".", 3), (",", ".", 3),
                                            (";", ",", 0), ("\t", ".", 0), (";", ".", 3)])
def test_files_without_thousands_separators_are_read_to_the_digit(tmp_path, sep, dec, digits):
    """Decimal commas or points, µm with 3 decimals (every cell under 1000 µm has the form of a thousands group) or
    whole, any separator: the values written, to the digit (the reference: the dataset's own numbers)."""
    path = tmp_path / "grid.csv"
    path.write_text(_export(sep, dec, "", digits))
    _, _, q, xyz = _grid()
    meas = _read(path)
    np.testing.assert_allclose(np.rad2deg(meas.q), q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(meas.xyz * 1e6, np.round(xyz, digits), rtol=0, atol=1e-6)
    np.testing.assert_allclose(_stream(path, ["x", "y", "z"]), np.round(xyz, digits), rtol=0, atol=1e-6)


@pytest.mark.parametrize("sep,dec,thousands,cell", [(";", ",", ".", "-432.471,963"), (",", ".", ",", "-432,471.963"),
                                                   ("\t", ".", ",", "-432,471.963")])
def test_a_cell_with_thousands_separators_is_said_to_have_them(tmp_path, sep, dec, thousands, cell):
    """'-432.471,963' in a ';' file was refused as "a decimal comma: use '.' or a ';' separated file" (it is one):
    the message names the thousands separator, in both readers."""
    path = tmp_path / "grid.csv"
    path.write_text(_export(sep, dec, thousands, 3))
    words = f"row 2, column 'x': '{cell}' is not a number ('{thousands}' as a thousands separator: write the numbers " \
            f"without thousands separators"
    with pytest.raises(MeasurementError) as err:
        _read(path)
    assert words in str(err.value) and "decimal comma" not in str(err.value)
    with pytest.raises(MeasurementError) as err:
        _stream(path, ["x"])
    assert words.replace("a number", "a finite number") in str(err.value)


def _targets(tmp_path, spoil=None, sep=",", dec="."):
    """The grid set's first 20 poses as compensation targets (joints deg, positions mm), ``spoil(cells)`` done to
    the 7th pose's cells, written with ``sep`` and ``dec``."""
    head, body, _, _ = _grid()
    keep = UR5_COLS + ["x", "y", "z"]
    rows = [[r[head.index(c)] for c in keep] for r in body[:20]]
    if spoil:
        spoil(rows[6], keep.index)
    path = tmp_path / "targets.csv"
    path.write_text("\n".join(sep.join(c.replace(".", dec) for c in r) for r in [keep] + rows) + "\n")
    return path


def _compensate(src):
    from kincal.compensate import StreamJob, TargetsFormat, compensate_file
    ur5 = kincal.load_robot("ur5")
    job = StreamJob(kincal.perturb(ur5, seed=1), ur5, TargetsFormat(joint_cols=tuple(UR5_COLS), length_unit="mm",
                                                                             angle_unit="deg"))
    return compensate_file(job, str(src), str(src.parent / "commands.csv"))


@pytest.mark.parametrize("col,value,words", [
    ("x", "1e300", "row 8, column 'x': 1e+300 mm is not physically possible for a robot (beyond 10 km"),
    ("joint_2", "1e300", "row 8, column 'joint_2': 1e+300 deg is not physically possible for a robot (beyond "
                         "100000 rad"),
    ("z", "-2e7", "row 8, column 'z': -2e+07 mm is not physically possible")])
def test_the_targets_reader_refuses_what_the_measurement_reader_refuses(tmp_path, col, value, words):
    """A target 1e300 mm away was 'target inf mm from the base' (a row refused after an overflow); a joint at 1e300
    deg 'units, column order, TCP or frame?': the targets reader checks cells as the measurement reader does, with
    its message (20 km = 2e7 mm is past the 10 km limit, 1e300 deg past 1e5 rad)."""
    path = _targets(tmp_path, lambda r, at: r.__setitem__(at(col), value))
    with pytest.raises(MeasurementError) as table:
        kincal.read_measurements(path, kincal.load_robot("ur5"), UR5_COLS, length_unit="mm", angle_unit="deg")
    with pytest.raises(MeasurementError) as stream:
        _compensate(path)
    assert words in str(stream.value) and str(stream.value) == str(table.value)


def test_a_comma_file_with_decimal_commas_is_said_to_be_one_by_the_targets_reader(tmp_path):
    path = _targets(tmp_path, dec=",")
    with pytest.raises(MeasurementError, match="row 2 has 18 fields, the header has 9 .decimal commas in a "
                                               "comma-separated file. use ';' as the separator"):
        _compensate(path)
    semi = _compensate(_targets(tmp_path, sep=";", dec=","))  # the same values, separated by ';': read alike
    plain = _compensate(_targets(tmp_path))
    assert semi.targets == 20 and (semi.accepted, semi.problems) == (plain.accepted, plain.problems)


def test_rows_of_separators_after_the_data_are_not_data_and_among_them_are_named(tmp_path):
    """Excel leaves ',,,,,,' rows below its table: they were 'row 22, column 'joint_1': '' is not a number'; at the
    end they are dropped (the file reads as without them, in both readers); among the data such a row is named as
    empty (a reading lost there, or a row cleared: the user decides)."""
    clean = _targets(tmp_path)
    ref = np.loadtxt(clean, delimiter=",", skiprows=1)  # (20, 9) deg, mm
    trailing = tmp_path / "trailing.csv"
    trailing.write_text(clean.read_text() + ",,,,,,,,\n" * 3 + '"","","","","","","","",""\n\n')
    meas = kincal.read_measurements(trailing, kincal.load_robot("ur5"), UR5_COLS, length_unit="mm", angle_unit="deg")
    np.testing.assert_allclose(np.c_[np.rad2deg(meas.q), meas.xyz * 1e3], ref, rtol=0, atol=1e-9)
    stream = open_stream(str(trailing), block_bytes=300)  # several blocks
    assert stream.size == clean.stat().st_size
    rows, values = (np.concatenate(a) for a in zip(*(stream.numbers(b, UR5_COLS + ["x", "y", "z"])
                                                      for b, _ in stream.blocks())))
    assert rows.tolist() == list(range(2, 22)) and np.array_equal(values, ref)
    assert _compensate(trailing).targets == 20
    lines = clean.read_text().splitlines()
    middle = tmp_path / "middle.csv"
    middle.write_text("\n".join(lines[:5] + [",,,,,,,,"] + lines[5:]) + "\n")
    with pytest.raises(MeasurementError, match="middle.csv: row 6 is empty .only separators.* delete the row"):
        kincal.read_measurements(middle, kincal.load_robot("ur5"), UR5_COLS, length_unit="mm", angle_unit="deg")
    with pytest.raises(MeasurementError, match="middle.csv: row 6 is empty .only separators.* delete the row"):
        _compensate(middle)


@pytest.mark.parametrize("col,suffix,words", [
    ("joint_1", " deg", "the unit 'deg' is written in the cell: write the number alone and give the unit as the "
                        "file's angle unit, angle_unit='deg' (CLI: --angle-unit deg)"),
    ("joint_1", "°", "the unit '°' is written in the cell: write the number alone and give the unit as the file's "
                     "angle unit, angle_unit='deg' (CLI: --angle-unit deg)"),
    ("x", " mm", "the unit 'mm' is written in the cell: write the number alone and give the unit as the file's "
                 "length unit, length_unit='mm' (CLI: --length-unit mm)")])
def test_a_unit_written_in_a_cell_is_named(tmp_path, col, suffix, words):
    path = _targets(tmp_path, lambda r, at: r.__setitem__(at(col), r[at(col)] + suffix))
    with pytest.raises(MeasurementError) as err:
        kincal.read_measurements(path, kincal.load_robot("ur5"), UR5_COLS, length_unit="mm", angle_unit="deg")
    assert f"row 8, column '{col}'" in str(err.value) and words in str(err.value)
    with pytest.raises(MeasurementError) as err:
        _compensate(path)
    assert f"row 8, column '{col}'" in str(err.value) and words in str(err.value)
