"""Hints for user mistakes (core/hints.py): the closest known name, only where one is close."""

from pma_model_ros.core.hints import did_you_mean, length_hint, missing_key, unknown_keys


def test_the_closest_known_name_is_suggested_and_none_when_nothing_is_close():
    assert did_you_mean('lenght_range', ['length_range', 'pressure_range']) == (
        " (did you mean 'length_range'?)"
    )
    assert did_you_mean('colour', ['length_range', 'pressure_range']) == ''


def test_unknown_and_missing_keys_name_the_misspelling_the_same_way():
    mapping = {'modle': 'martens', 'colour': 'red'}
    assert unknown_keys(mapping, ['model', 'models'], 'm.') == [
        "unknown key 'm.modle' (did you mean 'm.model'?)",
        "unknown key 'm.colour'",
    ]
    assert missing_key('model', mapping, ['model']) == (
        "unknown key 'modle' (did you mean 'model'?)"
    )
    assert missing_key('length_range', mapping, ['model']) == "'length_range' is missing"


def test_a_length_hint_names_the_unit_nearest_the_reference_among_those_taken():
    # 30 against a 0.274 m muscle: 30 cm (ratio 1.09), not 30 mm (ratio 0.11)
    assert length_hint(30, 0.274) == 'cm? 30 cm = 0.3 m'
    assert length_hint(274, 0.274) == 'mm? 274 mm = 0.274 m'
    # 900 against a 9 m muscle is 9 m in cm, but 9 m is not taken up to 5 m: 900 mm
    assert length_hint(900, 9.0) == 'cm? 900 cm = 9 m'
    assert length_hint(900, 9.0, (0.04, 5.0)) == 'mm? 900 mm = 0.9 m'
    assert length_hint(3e6, 0.3, (0.04, 9.0)) == ''  # 3 km in mm: no unit makes it a muscle
