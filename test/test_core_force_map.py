"""Force maps and their CSV files (core/identification/force_map.py)."""

import numpy as np
import pytest

from pma_model_ros.core.identification.force_map import (
    ForceMap,
    parse_force_map_csv,
    read_force_map_csv,
)

CSV = """# two lengths, two pressures
pressure_pa,length_m,force_n
0,0.2,0
300000,0.2,120.5
0,0.25,0
300000,0.25,410
"""


def test_reads_the_points_and_skips_comments(tmp_path):
    path = tmp_path / 'map.csv'
    path.write_text(CSV, encoding='utf-8')
    fmap = read_force_map_csv(path)
    np.testing.assert_array_equal(fmap.pressure, [0, 3e5, 0, 3e5])
    np.testing.assert_array_equal(fmap.length, [0.2, 0.2, 0.25, 0.25])
    np.testing.assert_array_equal(fmap.force, [0, 120.5, 0, 410])
    np.testing.assert_array_equal(fmap.lengths, [0.25, 0.2])  # descending
    assert fmap.max_force == 410


def test_the_direction_column_is_each_points_branch():
    text = 'pressure_pa,length_m,force_n,direction\n1e5,0.2,10,1\n1e5,0.2,6,-1\n2e5,0.25,30,1\n'
    fmap = parse_force_map_csv(text, 'branches')
    np.testing.assert_array_equal(fmap.direction, [1, -1, 1])
    with pytest.raises(ValueError, match='direction must be'):
        parse_force_map_csv(text.replace(',-1\n', ',0\n'), 'branches')


@pytest.mark.parametrize(
    ('text', 'message'),
    [
        ('pressure,length,force\n0,0.2,0\n', 'header must be'),
        ('pressure_pa,length_m,force_n\n0,0.2,nan\n', 'NaN or infinite'),
        ('pressure_pa,length_m,force_n\n0,0.2\n', 'line 2 is not 3 numbers'),
        ('pressure_pa,length_m,force_n\n', 'no data rows'),
    ],
)
def test_bad_files_name_the_source_and_the_problem(text, message):
    with pytest.raises(ValueError, match=message) as err:
        parse_force_map_csv(text, 'user.csv')
    assert str(err.value).startswith('user.csv: ')


def test_millimetres_are_refused():
    with pytest.raises(ValueError, match=r'mm\? 250 mm = 0.25 m$'):
        ForceMap([0, 1e5, 2e5], [200, 200, 250], [0, 50, 90])


def test_a_byte_order_mark_is_not_part_of_the_header(tmp_path):
    """Spreadsheets export 'CSV UTF-8' with a byte-order mark before the header."""
    path = tmp_path / 'map.csv'
    path.write_text(CSV, encoding='utf-8-sig')
    assert path.read_bytes().startswith(b'\xef\xbb\xbf')
    np.testing.assert_array_equal(read_force_map_csv(path).force, [0, 120.5, 0, 410])


@pytest.mark.parametrize('separator, name', [(';', 'semicolons'), ('\t', 'tabs')])
def test_another_separator_is_named(separator, name):
    text = CSV.replace(',', separator)
    with pytest.raises(ValueError, match=f'^user.csv: columns separated by {name}; '):
        parse_force_map_csv(text, 'user.csv')


def test_a_row_in_another_separator_is_named_on_its_line():
    """A comma header and one row typed with semicolons: its line, its text and the separator."""
    text = 'pressure_pa,length_m,force_n\n5000,0.25,0\n5000;0.234;0\n'
    with pytest.raises(ValueError) as error:
        parse_force_map_csv(text, 'user.csv')
    assert str(error.value) == (
        "user.csv: line 3 is not 3 numbers: '5000;0.234;0'; columns separated by semicolons, "
        'where commas separate them'
    )


def test_a_decimal_comma_is_named():
    """0,25 m written with a decimal comma: four fields where the header has three."""
    text = 'pressure_pa,length_m,force_n\n300000,0,25,410\n'
    with pytest.raises(ValueError, match='line 2 has 4 fields, the header 3; decimals'):
        parse_force_map_csv(text, 'user.csv')


def test_rows_are_named_by_the_line_of_the_file():
    """A comment, the header and 9 data rows, the 9th bad: line 11 of the file, as an editor
    numbers it; a blank line counts too.  Each point keeps its line.
    """
    rows = [f'{p},0.2,{p / 1e4}' for p in range(0, 800000, 100000)]
    text = '# a map\npressure_pa,length_m,force_n\n' + '\n'.join(rows) + '\n900000,0.2,x\n'
    with pytest.raises(ValueError, match='^user.csv: line 11 is not 3 numbers'):
        parse_force_map_csv(text, 'user.csv')
    fmap = parse_force_map_csv(text.replace(',x', ',90').replace('# a map', '# a map\n'), 'u')
    assert fmap.line.tolist() == list(range(4, 13))
    assert fmap.subset(fmap.force >= 50).line.tolist() == [9, 10, 11, 12]


@pytest.mark.parametrize(
    'text, message',
    [
        ('', 'user.csv: the file is empty; a force map CSV starts with the header pressure_pa,'),
        ('# only\n\n# comments\n', 'user.csv: the file is empty but for comments; a force map'),
        ('p,L,F\n1,2,3\n', 'user.csv: line 1: header must be pressure_pa,length_m,force_n'),
    ],
)
def test_an_empty_file_or_a_wrong_header_is_named(text, message):
    """An empty file is no header problem; a wrong header names its line."""
    with pytest.raises(ValueError, match=message):
        parse_force_map_csv(text, 'user.csv')


def test_a_subset_keeps_the_chosen_points():
    fmap = ForceMap([0, 1e5, 2e5, 3e5], [0.2, 0.2, 0.25, 0.25], [0, 50, 90, 120])
    assert fmap.subset(np.array([False, True, True, True])).force.tolist() == [50, 90, 120]


@pytest.mark.parametrize(
    ('pressures', 'lengths', 'hint'),
    [
        # Table A2's 650 kPa top in bar, kPa, MPa and psi (1 psi = 6894.757 Pa)
        ([0, 3, 6.5], [0.2, 0.2, 0.25], r'reaches only 6.5 Pa.*; bar\? 6.5 bar = 650000 Pa$'),
        ([0, 300, 650], [0.2, 0.2, 0.25], r'reaches only 650 Pa.*; kPa\? 650 kPa = 650000 Pa$'),
        ([0, 0.3, 0.65], [0.2, 0.2, 0.25], r'; MPa\? 0.65 MPa = 650000 Pa$'),
        ([0, 43.5, 94.27], [0.2, 0.2, 0.25], r'; psi\? 94.27 psi = 649969 Pa$'),
        (
            [-5e3, 3e5, 6e5],
            [0.2, 0.2, 0.25],
            r'>= 0 Pa \(absolute - ambient\), got -5000 at line 2$',
        ),
        ([-6e5, 3e5, 6e5], [0.2, 0.2, 0.25], r'got -600000 at line 2; that is below vacuum$'),
        ([0, 3e5, 6e5], [20, 20, 25], r'got 20..25; cm\? 25 cm = 0.25 m$'),
        ([0, 3e5, 6e5], [200, 200, 250], r'got 200..250; mm\? 250 mm = 0.25 m$'),
    ],
)
def test_a_csv_in_other_units_gets_the_hint_of_its_case(pressures, lengths, hint):
    text = 'pressure_pa,length_m,force_n\n' + ''.join(
        f'{p},{L},{F}\n' for p, L, F in zip(pressures, lengths, [0, 50, 90])
    )
    with pytest.raises(ValueError, match=hint):
        parse_force_map_csv(text, 'map.csv')


def test_a_value_out_of_range_names_its_line():
    """A negative force on line 4 (after the header and a comment), 60 bar typed as 6e6 Pa on 5."""
    text = 'pressure_pa,length_m,force_n\n# c\n1e5,0.2,5\n2e5,0.2,-3\n3e5,0.25,9\n'
    with pytest.raises(ValueError, match=r'a muscle only pulls\), got -3 at line 4$'):
        parse_force_map_csv(text, 'map.csv')
    text = text.replace(',-3', ',3').replace('3e5,', '6e6,')
    with pytest.raises(ValueError, match=r'\(0..5e6\), got 6e\+06 at line 5$'):
        parse_force_map_csv(text, 'map.csv')
