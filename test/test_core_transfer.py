"""Cut-to-length transfer (core/identification/transfer.py): the same muscle type at another rest
length.
"""

import copy
import math

import numpy as np
import pytest

from conftest import CONFIGS, REPO
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.identification import transfer
from pma_model_ros.core.identification.transfer import EXPONENTS, scale_parameters
from pma_model_ros.core.physics.flags import Flag
from pma_model_ros.core.physics.models import force_raw, get_model, MODELS

#: New rest lengths [m]: far shorter, a little shorter, longer.
NEW_LENGTHS = (0.05, 0.274, 1.7)
#: Every shipped parameter file of one muscle: the configs, the docs' examples, and the model_node
#: section of the composed example (:func:`read_parameters` reads a file's first node).
SHIPPED = {
    **CONFIGS,
    **{p.stem: p for p in sorted((REPO / 'docs' / 'examples').glob('*.yaml'))},
    'composed': REPO / 'config' / 'example_composed.yaml',
}


def _close(a, b, rel=1e-9):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= rel * np.abs(b)))


@pytest.mark.parametrize('muscle', sorted(SHIPPED))
@pytest.mark.parametrize('length', NEW_LENGTHS)
def test_round_trip_gives_the_source_back(muscle, length):
    source = read_parameters(SHIPPED[muscle])
    there, _ = scale_parameters(source, length)
    back, _ = scale_parameters(there, source['muscle']['nominal_length'])
    assert back['muscle'] == source['muscle']
    assert _close(back['length_range'], source['length_range'])
    assert back['models'].keys() == source['models'].keys()
    for name, block in source['models'].items():
        ours = back['models'][name]
        assert _close(ours.get('params', []), block.get('params', [])), name
        if 'held_out' in block:
            assert _close(ours['held_out']['lengths'], block['held_out']['lengths'])
            assert ours['held_out']['err'] == block['held_out']['err']
    for key in ('joint_name', 'frame_id'):
        assert back.get(key) == source.get(key)
    assert source == read_parameters(SHIPPED[muscle])  # the source mapping is not changed


def _grid(parameters):
    """Pressures [Pa] and contractions [-] across and beyond the identified domain."""
    l0 = parameters['muscle']['nominal_length']
    low, high = parameters['length_range']
    kappa = np.linspace((l0 - high) / l0 - 0.03, (l0 - low) / l0 + 0.05, 13)
    pressure = np.linspace(0.0, 7e5, 11)
    return np.meshgrid(pressure, kappa)


@pytest.mark.parametrize('muscle', sorted(SHIPPED))
@pytest.mark.parametrize('length', NEW_LENGTHS)
def test_every_model_serves_the_same_force_at_equal_contraction_and_pressure(muscle, length):
    """The served force and its flags, in and outside the identified box, for each model."""
    source = read_parameters(SHIPPED[muscle])
    target, _ = scale_parameters(source, length)
    pressure, kappa = _grid(source)
    for name in source['models']:
        old, new = muscle_model(source, name), muscle_model(target, name)
        a = old.force(pressure, (1 - kappa) * old.spec.nominal_length)
        b = new.force(pressure, (1 - kappa) * new.spec.nominal_length)
        scale = np.nanmax(np.abs(a.force))
        # CLIPPED (the raw force below 0) is the sign of a rounding error where the raw force is 0
        # (at L0 without pressure, eq. 14's elastic terms vanish): compared where it is not
        zero = np.abs(np.nan_to_num(a.raw)) <= 1e-9 * scale
        assert np.array_equal(a.flags | zero * Flag.CLIPPED, b.flags | zero * Flag.CLIPPED), name
        assert np.allclose(a.force, b.force, rtol=0, atol=1e-9 * scale, equal_nan=True), name


def _chou_hannaford_martens(pressure, kappa, d0, h0, angle, modulus):
    """Martens' eq. 14 at a constant modulus E, written in the contraction kappa alone (no L0).

    With w = sqrt(1 - (1 - kappa)^2 cos^2 Theta), eqs. 2-4 give D = D0 w / sin Theta,
    L0 dD/dL = -(1 - kappa) D0 cos^2 Theta / (sin Theta w) and -dV/dL = pi D0^2 / 4
    (3 (1 - kappa)^2 / tan^2 Theta - 1 / sin^2 Theta); F_PE = E (D / D0 - 1) H0 (1 - kappa) L0 pi,
    F_L = -E kappa H0 pi D.
    """
    c, s = math.cos(angle), math.sin(angle)
    w = np.sqrt(1 - (1 - kappa) ** 2 * c**2)
    pull = (
        pressure * math.pi * d0**2 / 4 * (3 * (1 - kappa) ** 2 / math.tan(angle) ** 2 - 1 / s**2)
    )
    f_pe_slope = -modulus * h0 * math.pi * d0 * (1 - kappa) ** 2 * c**2 * (w - s) / (s**2 * w)
    f_l = -modulus * kappa * h0 * math.pi * d0 * w / s
    return pull + f_pe_slope - f_l


def test_martens_constant_modulus_is_the_hand_derived_force_at_every_cut():
    """Eq. 14 with E = 2 MPa and a braid-angle correction of 0.05 rad: a constant modulus keeps its
    parameters, and the source and each cut give the force derived by hand in kappa alone.
    """
    source = read_parameters(CONFIGS['DMSP-20-300'])
    source['models'] = {'martens': {'params': [2e6, 0.0, 0.0, 0.0, 0.05]}}
    spec = source['muscle']
    pressure, kappa = np.meshgrid(np.linspace(0, 6e5, 7), np.linspace(0, 0.25, 11))
    expected = _chou_hannaford_martens(
        pressure,
        kappa,
        spec['inner_diameter'],
        spec['membrane_thickness'],
        spec['fiber_angle'] + 0.05,
        2e6,
    )
    assert np.ptp(expected[:, -1]) > 100  # the case is not trivial: the force varies with kappa
    for parameters in [source] + [scale_parameters(source, L)[0] for L in NEW_LENGTHS]:
        assert parameters['models']['martens']['params'] == [2e6, 0.0, 0.0, 0.0, 0.05]
        muscle = muscle_model(parameters, 'martens')
        l0 = muscle.spec.nominal_length
        got = force_raw(
            muscle.model, muscle.theta, muscle.spec, muscle.domain, pressure, (1 - kappa) * l0
        )
        assert np.allclose(got, expected, rtol=1e-12, atol=1e-9), l0


def test_mckibben_at_rest_length_is_chou_hannaford_whatever_the_cut():
    """Eq. 17 at L = L0: p pi D0^2 / 4 (3 / tan^2 Theta0 - 1 / sin^2 Theta0), no L0 in it."""
    source = read_parameters(CONFIGS['DMSP-20-300'])
    spec = source['muscle']
    th = spec['fiber_angle']
    expected = (
        5e5
        * math.pi
        * spec['inner_diameter'] ** 2
        / 4
        * (3 / math.tan(th) ** 2 - 1 / math.sin(th) ** 2)
    )
    for length in NEW_LENGTHS:
        muscle = muscle_model(scale_parameters(source, length)[0], 'mckibben')
        got = force_raw(muscle.model, muscle.theta, muscle.spec, muscle.domain, 5e5, length)
        assert got == pytest.approx(expected, rel=1e-12)


def test_parameters_scale_by_the_power_of_their_length_unit():
    """Martens' E_RU coefficient of L^j [Pa/m^j] by s^-j, Hildebrandt's d4 of L^(2/3) by s^-2/3,
    Wickramatunge's by s^-1, s^-3, s^-2, s^-1; dimensionless ones stay.
    """
    source = read_parameters(CONFIGS['DMSP-20-300'])
    s = 0.274 / 0.3
    target, _ = scale_parameters(source, 0.274)
    expect = {
        'martens': [1, s**-1, s**-2, s**-3, 1],
        'hildebrandt': [1, s**-1, s**-2, 1, s**-1, s**-2, s**-3, s ** (-2 / 3)],
        'wickramatunge': [s**-1, s**-3, s**-2, s**-1],
        'sarosi': [1] * 6,
        'andrikopoulos': [1, 1],
    }
    for name, factors in expect.items():
        old = np.array(source['models'][name]['params'])
        assert _close(target['models'][name]['params'], old * factors), name


def test_the_domain_moves_in_contraction():
    source = read_parameters(CONFIGS['DMSP-20-300'])
    target, _ = scale_parameters(source, 0.274)
    s = 0.274 / 0.3
    assert target['muscle']['nominal_length'] == 0.274
    assert _close(target['length_range'], [0.222 * s, 0.296 * s], rel=1e-11)
    assert target['pressure_range'] == source['pressure_range']
    held = target['models']['martens']['held_out']
    assert _close(
        held['lengths'],
        np.array(source['models']['martens']['held_out']['lengths']) * s,
        rel=1e-11,
    )
    assert held['max_force'] == source['models']['martens']['held_out']['max_force']
    domain = muscle_model(target, 'martens').domain
    assert (domain.length_min, domain.length_max) == pytest.approx((0.222 * s, 0.296 * s))
    for key in ('inner_diameter', 'membrane_thickness', 'fiber_angle', 'max_pressure'):
        assert target['muscle'][key] == source['muscle'][key]


def test_a_calibrated_rest_length_scales_and_a_pressure_offset_stays():
    source = read_parameters(CONFIGS['DMSP-20-300'])
    block = source['models']['martens']
    block.update(nominal_length=0.305, pressure_offset=12e3)
    target, _ = scale_parameters(source, 0.6)
    assert target['models']['martens']['nominal_length'] == pytest.approx(0.61, rel=1e-12)
    assert target['models']['martens']['pressure_offset'] == 12e3
    old, new = muscle_model(source, 'martens'), muscle_model(target, 'martens')
    kappa = np.linspace(0.0, 0.25, 9)
    a = old.force(4e5, (1 - kappa) * 0.305).force
    b = new.force(4e5, (1 - kappa) * 0.61).force
    assert np.allclose(a, b, rtol=1e-9)


def test_names_follow_the_new_length_unless_set_by_hand():
    source = read_parameters(CONFIGS['DMSP-20-300'])
    target, notes = scale_parameters(source, 0.274)
    assert (target['muscle']['name'], target['joint_name'], target['frame_id']) == (
        'DMSP-20-274',
        'DMSP-20-274',
        'dmsp_20_274',
    )
    assert notes == []
    assert transfer.renamed('AARL-DMSP-20-274', 0.274, 0.3) == 'AARL-DMSP-20-300'
    assert transfer.renamed('my muscle', 0.274, 0.3005) == 'my muscle-300.5'
    # a calibrated L0 (here 1.5 % above the given 274 mm) keeps the given one's name
    assert transfer.renamed('AARL-DMSP-20-274', 0.27811, 0.3) == 'AARL-DMSP-20-300'
    assert transfer.renamed('DMSP-20-100', 0.3, 0.274) == 'DMSP-20-100-274'
    source.update(joint_name='elbow_flexor', hardware_id='rig-3')
    target, notes = scale_parameters(source, 0.274)
    assert target['joint_name'] == 'elbow_flexor' and target['hardware_id'] == 'rig-3'
    assert notes == ["joint_name 'elbow_flexor' kept as set", "hardware_id 'rig-3' kept as set"]


def test_hysteresis_settings_are_kept_and_said_so():
    source = read_parameters(CONFIGS['DMSP-10-100'])
    source['hysteresis'] = {'input': 'length', 'length_deadband': 0.001}
    target, notes = scale_parameters(source, 0.3)
    assert target['hysteresis'] == source['hysteresis']
    assert notes == ["hysteresis settings kept: deadbands are the sensors', not the muscle's"]


def test_every_model_has_one_exponent_per_parameter():
    assert set(EXPONENTS) == set(MODELS)
    for name, model in MODELS.items():
        assert len(EXPONENTS[name]) == model.n_params, name


def test_a_model_without_a_transfer_is_refused_by_name(monkeypatch):
    monkeypatch.delitem(EXPONENTS, 'hildebrandt')
    with pytest.raises(ValueError, match=r"^model 'hildebrandt' has no cut-to-length transfer"):
        scale_parameters(read_parameters(CONFIGS['DMSP-20-300']), 0.274)


@pytest.mark.parametrize(
    'length, message',
    [
        (0.0, r'must be in \[0\.04, 9\] m \(the lengths Festo cuts a DMSP to\), got 0\.0$'),
        (-0.3, r'got -0\.3$'),
        (math.nan, r'got nan$'),
        (math.inf, r'got inf$'),
        # a 1 cm DMSP-20: shorter than any Festo cuts, and no unit makes it one
        (0.01, r'got 0\.01$'),
        (9.5, r'got 9\.5; cm\? 9\.5 cm = 0\.095 m$'),
        # the unit whose length is nearest the source's 0.3 m: 30 cm (30 mm is 10 times off)
        (30.0, r'got 30\.0; cm\? 30 cm = 0\.3 m$'),
        (300.0, r'got 300\.0; mm\? 300 mm = 0\.3 m$'),
        (3e6, r'got 3000000\.0$'),  # beyond 9 m in mm too: no unit named
        (True, r'must be a number in m'),
    ],
)
def test_a_bad_rest_length_is_refused(length, message):
    with pytest.raises(ValueError, match=message):
        scale_parameters(read_parameters(CONFIGS['DMSP-20-300']), length)


def test_the_festo_lengths_are_taken():
    for length in transfer.FESTO_LENGTHS:
        target, _ = scale_parameters(read_parameters(CONFIGS['DMSP-20-300']), length)
        assert target['muscle']['nominal_length'] == length


def _calibrated(given=0.3, calibrated=0.305):
    """DMSP-20-300's file as ``pma-model fit`` writes a calibrated one: the given L0 as
    muscle.given_nominal_length, the default model's calibrated L0 as muscle.nominal_length and
    in its block.
    """
    source = read_parameters(CONFIGS['DMSP-20-300'])
    source['muscle'].update(nominal_length=calibrated, given_nominal_length=given)
    source['models']['martens']['nominal_length'] = calibrated
    return source


def test_the_new_length_is_the_given_one_and_a_calibrated_l0_moves_by_the_same_factor():
    """Cut to a measured 0.398 m: s = 0.398 / 0.3 (the given L0s), the calibrated 0.305 m
    becomes 0.305 s, the name follows the given length, and the source's force at its measured
    rest length 0.3 m is served at 0.398 m.
    """
    source = _calibrated()
    target, _ = scale_parameters(source, 0.398)
    s = 0.398 / 0.3
    muscle = target['muscle']
    assert muscle['name'] == 'DMSP-20-398' and muscle['given_nominal_length'] == 0.398
    assert muscle['nominal_length'] == pytest.approx(0.305 * s, rel=1e-12)
    assert target['models']['martens']['nominal_length'] == pytest.approx(0.305 * s, rel=1e-12)
    assert _close(target['length_range'], [0.222 * s, 0.296 * s], rel=1e-11)
    old, new = muscle_model(source, 'martens'), muscle_model(target, 'martens')
    pressure = np.linspace(1e5, 6e5, 6)
    for length in (0.3, 0.29, 0.25):  # beyond, inside the identified lengths
        a, b = old.force(pressure, length), new.force(pressure, length * s)
        assert np.allclose(a.force, b.force, rtol=1e-9) and np.all(a.flags == b.flags)
    for model in source['models']:  # every model of the file moves with it
        old, new = muscle_model(source, model), muscle_model(target, model)
        a, b = old.force(pressure, 0.26), new.force(pressure, 0.26 * s)
        # to 1e-9 of the largest force, as every model's transfer (the parameters' rounding)
        assert np.allclose(a.force, b.force, rtol=0, atol=1e-9 * a.force.max()), model
    back, _ = scale_parameters(target, 0.3)
    assert back['muscle']['given_nominal_length'] == 0.3
    assert back['muscle']['name'] == 'DMSP-20-300'
    assert back['muscle']['nominal_length'] == pytest.approx(0.305, rel=1e-12)
    assert _close(back['models']['martens']['params'], source['models']['martens']['params'])


def test_the_given_length_of_a_file_without_the_key():
    """A calibrated file without muscle.given_nominal_length: the given L0 of its header (as
    ``pma-model fit`` writes it), else its muscle.nominal_length with a note when that is the
    default model's calibrated L0.
    """
    source = _calibrated()
    del source['muscle']['given_nominal_length']
    header = (
        '# DMSP-20-300 identified ... (geometry calibration ON; given nominal_length 0.3 m).\n'
    )
    given, note = transfer.given_length(source, header)
    assert given == 0.3
    assert note == (
        'given L0 0.3 m read from the header (muscle.nominal_length 0.305 m is the calibrated one)'
    )
    given, note = transfer.given_length(source)
    assert given == 0.305 and 'no given L0 in the file' in note
    target, _ = scale_parameters(source, 0.398, given=0.3)
    assert target['muscle']['given_nominal_length'] == 0.398
    assert target['muscle']['nominal_length'] == pytest.approx(0.305 * 0.398 / 0.3, rel=1e-12)
    plain = read_parameters(CONFIGS['DMSP-20-300'])
    assert transfer.given_length(plain) == (0.3, '')
    assert 'given_nominal_length' not in scale_parameters(plain, 0.274)[0]['muscle']


def test_a_calibrated_rest_length_beyond_physics_is_refused():
    """A cut whose calibrated L0 would pass 10 m: the spec's own refusal, before anything is
    written.
    """
    source = read_parameters(CONFIGS['DMSP-20-300'])
    source['models']['martens']['nominal_length'] = 0.35
    with pytest.raises(ValueError, match='nominal_length'):
        scale_parameters(source, 9.0)


def test_a_file_of_several_muscles_is_refused():
    source = read_parameters(CONFIGS['DMSP-20-300'])
    with pytest.raises(ValueError, match="'muscles:'"):
        scale_parameters({'muscles': ['a'], 'a': copy.deepcopy(source)}, 0.2)


def test_the_model_names_are_the_models():
    for name in EXPONENTS:
        assert get_model(name).name == name
