"""Hints for user mistakes (core/hints.py): the closest known name, only where one is close."""

from pma_model_ros.core.hints import did_you_mean, missing_key, unknown_keys


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
