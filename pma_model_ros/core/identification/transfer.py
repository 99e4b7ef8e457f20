"""Cut-to-length transfer: an identified muscle as the same type cut to another rest length.

A Festo DMSP is sold by diameter and cut to any length.  Cutting keeps the tube and the braid (the
inner diameter D0, the membrane thickness H0, the braid angle Theta0 and the rated pressure) and
scales what is counted along the axis: the fibre length L_F = L0 / cos(Theta0) and the number of
turns n = L0 tan(Theta0) / (pi D0) (eq. 3) both grow with L0.  With s = L0' / L0 and lengths at
equal contraction kappa = (L0 - L) / L0 (L' = s L):

* the diameter D = sqrt(L_F^2 - L^2) / (n pi) (eq. 2) is the same, its slope dD/dL is 1/s times;
* the volume slope dV/dL = (L_F^2 - 3 L^2) / (4 pi n^2) (eq. 4) is the same: the pressure force
  -p dV/dL (eqs. 14, 17) is p pi D0^2 / 4 (3 (1 - kappa)^2 / tan^2 Theta0 - 1 / sin^2 Theta0);
* Martens' elastic forces (eqs. 10-13): F_PE = E (D - D0) / D0 H0 L pi is s times, F_PE dD/dL the
  same, F_L = E (L - L0) / L0 H0 pi D the same, at an equal modulus E.  The modulus is a material
  property at a strain: equal at equal contraction, so E_RU'(s L) = E_RU(L) (eq. 15).

So the force F(p, kappa) of an ideal braid does not depend on the cut length, and every model here
is moved by rewriting its parameters so that F'(p, s L) = F(p, L) exactly.  Each parameter is
multiplied by s**k, k from :data:`EXPONENTS`:

============================  =====================================  =========================
model (equation)              parameters                             k
============================  =====================================  =========================
mckibben (eq. 17)             none                                   --
andrikopoulos (eq. 18)        c0, c1 (functions of kappa)            0, 0
sarosi (eq. 19), hysteresis   all (functions of kappa)               0
hildebrandt (eq. 20)          c_j, d_j of L^j (j = 0..3); d4 of      -j; d4: -2/3
                              L^(2/3)
wickramatunge (eq. 21)        c0, c1, c2, c3 (dL = L - min L moves   -1, -3, -2, -1
                              with s)
martens (eqs. 14-16), _end    c_j of E_RU's L^j [Pa/m^j]; d0 [rad];  -j; 0; 0
                              end factor a [-]
a calibration                 nominal_length [m]; pressure_offset    1; 0
                              [Pa]
============================  =====================================  =========================

s is taken between GIVEN rest lengths, the ones a user measures: the new cut's and the source's
(:func:`given_length`: ``muscle.given_nominal_length``, written by ``pma-model fit`` beside a
calibrated ``muscle.nominal_length``).  A calibrated L0 moves by the same s, so the source's
measured rest-length row lands at the new cut's measured rest length.

A model missing from :data:`EXPONENTS` is refused by name.  The validity domain moves with the
muscle in contraction: ``length_range``, the held-out lengths and a calibrated ``nominal_length``
are multiplied by s; pressures, forces and errors in % of the max force are not.
"""

from __future__ import annotations

import copy
import math
import re

from .calibration import LENGTH_BOUND
from ..files.node_parameters import frame_of
from ..files.param_file import GIVEN_LENGTH, spec_mapping
from ..hints import length_hint
from ..physics.geometry import MuscleSpec
from ..physics.models import get_model

#: model name -> exponent k of each parameter: theta' = theta * s**k, s = L0' / L0 (module doc).
EXPONENTS: dict[str, tuple[float, ...]] = {
    'mckibben': (),
    'andrikopoulos': (0.0, 0.0),
    'wickramatunge': (-1.0, -3.0, -2.0, -1.0),
    'hildebrandt': (0.0, -1.0, -2.0, 0.0, -1.0, -2.0, -3.0, -2.0 / 3.0),
    'sarosi': (0.0,) * 6,
    'martens': (0.0, -1.0, -2.0, -3.0, 0.0),
    'martens_end': (0.0, -1.0, -2.0, -3.0, 0.0, 0.0),
    'sarosi_hysteresis': (0.0,) * 12,
}
#: significant digits of the written lengths (as the parameter writer's; parameters are written
#: in full, for the round trip)
_DIGITS = 12
#: [m] The rest lengths Festo cuts a DMSP to, every diameter: 40 to 9000 mm (Festo's catalogue).
#: Outside them no muscle of the type exists to serve.
FESTO_LENGTHS = (0.04, 9.0)
#: The header line ``pma-model fit`` writes the given rest length in (files without the key).
_HEADER_GIVEN = re.compile(r'given nominal_length ([0-9.eE+-]+) m')


def _num(value: float) -> float:
    return float(f'{value:.{_DIGITS}g}')


def _millimetres(length: float) -> str:
    return f'{length * 1e3:.4g}'


def renamed(name: str, old_length: float, new_length: float) -> str:
    """``<type>-<L0' in mm>``: a trailing ``-<number>`` of ``name`` replaced where it is the old
    rest length in mm (within :data:`~.calibration.LENGTH_BOUND`: a calibrated L0 keeps the given
    one's name), else ``-<L0' in mm>`` appended.
    """
    found = re.fullmatch(r'(.*)-(\d+(?:\.\d+)?)', name)
    if found and abs(float(found[2]) / 1e3 - old_length) <= LENGTH_BOUND * old_length:
        name = found[1]
    return f'{name}-{_millimetres(new_length)}'


def check_rest_length(length: object, reference: float) -> float:
    """``length`` [m] if a rest length Festo cuts (:data:`FESTO_LENGTHS`), else ValueError (one
    line; a number too large names the unit it looks like, by its ratio to ``reference`` [m], the
    source's given rest length).
    """
    if isinstance(length, bool) or not isinstance(length, (int, float)):
        raise ValueError(f'rest length must be a number in m, got {length!r}')
    low, high = FESTO_LENGTHS
    if not (math.isfinite(length) and low <= length <= high):
        hint = length_hint(length, reference, FESTO_LENGTHS) if length > high else ''
        raise ValueError(
            f'rest length must be in [{low:g}, {high:g}] m (the lengths Festo cuts a DMSP to), '
            f'got {length!r}' + (f'; {hint}' if hint else '')
        )
    return float(length)


def given_length(parameters: dict, header: str = '') -> tuple[float, str]:
    """The source's given rest length L0 [m] (as measured, before any calibration) and a note
    where it is not the file's key.

    ``muscle.given_nominal_length`` where the file has it; else the ``given nominal_length X m``
    of ``header`` (the file's comment lines, as ``pma-model fit`` writes them), noted; else
    ``muscle.nominal_length``, noted where it is the default model's calibrated L0 (then the given
    one is unknown).
    """
    muscle = _one_muscle(parameters)
    muscle = muscle if isinstance(muscle, dict) else {}
    if GIVEN_LENGTH in muscle:
        return _length(muscle[GIVEN_LENGTH], GIVEN_LENGTH, 'muscle'), ''
    length = _length(muscle.get('nominal_length'), 'nominal_length', 'muscle')
    found = _HEADER_GIVEN.search(header)
    if found:
        given = float(found[1])
        if given == length:
            return given, ''
        return given, (
            f'given L0 {given:g} m read from the header (muscle.nominal_length {length:g} m is '
            'the calibrated one)'
        )
    models = parameters.get('models')
    block = models.get(parameters.get('model')) if isinstance(models, dict) else None
    if isinstance(block, dict) and block.get('nominal_length') == length:
        return length, (
            f'no given L0 in the file: --length is taken in the sense of the calibrated L0 '
            f'{length:g} m; for a measured rest length X pass X x {length:g} / the given L0'
        )
    return length, ''


def scale_parameters(
    parameters: dict, nominal_length: float, given: float | None = None
) -> tuple[dict, list[str]]:
    """The ``ros__parameters`` of the muscle in ``parameters`` cut to the given rest length
    ``nominal_length``.

    Parameters
    ----------
    parameters : dict
        ``ros__parameters`` of one identified muscle (:mod:`~pma_model_ros.core.files.param_file`
        layout; SI units).
    nominal_length : float
        The new cut's given (measured) rest length L0' [m], in :data:`FESTO_LENGTHS`.
    given : float, optional
        The source's given rest length L0 [m] (default: :func:`given_length` of ``parameters``).

    Returns
    -------
    dict
        A new mapping (``parameters`` is not changed): every model's ``params`` multiplied by
        s**k (:data:`EXPONENTS`, s = L0' / L0), ``muscle.nominal_length``, ``length_range``, each
        model's calibrated ``nominal_length`` and held-out ``lengths`` [m] by s;
        ``muscle.given_nominal_length`` L0' (where the source has one or it differs from
        ``muscle.nominal_length``); the muscle renamed ``<type>-<L0' in mm>`` (:func:`renamed`),
        and ``joint_name`` / ``frame_id`` with it where they were the old name's.  Everything
        else (pressures, the identification figures, which are the source map's at equal
        contraction, node settings) is kept.
    list of str
        One note per thing kept that a user may want to set (a ``joint_name``, ``frame_id`` or
        ``hardware_id`` of their own).

    Raises
    ------
    ValueError
        A rest length Festo does not cut (:func:`check_rest_length`), a file of several muscles
        or joints, a model without a transfer (one line naming it), or a malformed block.

    """
    spec = MuscleSpec.from_mapping(spec_mapping(_one_muscle(parameters)))
    given = given_length(parameters)[0] if given is None else given
    nominal_length = check_rest_length(nominal_length, given)
    models = parameters.get('models')
    if not isinstance(models, dict):
        raise ValueError('models must be a mapping of model name -> block')
    for name in models:
        if get_model(name).name not in EXPONENTS:
            raise ValueError(f'model {name!r} has no cut-to-length transfer; remove its block')
    ratio = nominal_length / given
    out = copy.deepcopy(parameters)
    new_name = renamed(spec.name, given, nominal_length)
    muscle = out['muscle'] | {'name': new_name}
    if spec.nominal_length == given:  # the given L0 itself: the new one as typed
        muscle['nominal_length'] = _num(nominal_length)
    else:
        muscle['nominal_length'] = _num(spec.nominal_length * ratio)
    if GIVEN_LENGTH in muscle or muscle['nominal_length'] != nominal_length:
        muscle[GIVEN_LENGTH] = _num(nominal_length)
    out['muscle'] = muscle
    length_range = parameters.get('length_range')
    if not (isinstance(length_range, list) and len(length_range) == 2):
        raise ValueError(f'length_range must be [min, max] in m, got {length_range!r}')
    out['length_range'] = [_num(float(v) * ratio) for v in length_range]
    for name, block in out['models'].items():
        if not isinstance(block, dict):
            raise ValueError(f'models.{name} must be a mapping')
        model = get_model(name)
        exponents = EXPONENTS[model.name]
        if 'params' in block or exponents:
            theta = model.check_params(block.get('params', []))
            block['params'] = [v * ratio**k for v, k in zip(theta.tolist(), exponents)]
        if 'nominal_length' in block:
            block['nominal_length'] = _num(_length(block['nominal_length'], name) * ratio)
        held = block.get('held_out')
        if isinstance(held, dict) and isinstance(held.get('lengths'), list):
            held['lengths'] = [_num(_length(v, name) * ratio) for v in held['lengths']]
    notes = []
    for key, derived in (('joint_name', spec.name), ('frame_id', frame_of(spec.name))):
        value = parameters.get(key)
        if value == derived:
            out[key] = new_name if key == 'joint_name' else frame_of(new_name)
        elif value:
            notes.append(f'{key} {value!r} kept as set')
    if parameters.get('hardware_id'):
        notes.append(f'hardware_id {parameters["hardware_id"]!r} kept as set')
    if 'hysteresis' in parameters:
        notes.append("hysteresis settings kept: deadbands are the sensors', not the muscle's")
    from ..files.param_file import muscle_model  # every model of the new file builds

    for name in out['models']:
        muscle_model(out, name)
    return out, notes


def _one_muscle(parameters: dict) -> object:
    """The ``muscle`` entry of a file of one muscle; ValueError for a file of several or a joint
    file.
    """
    for key in ('muscles', 'joints'):
        if key in parameters:
            raise ValueError(
                f"a file with '{key}:' has no one muscle to cut; scale one muscle's file"
            )
    return parameters.get('muscle')


def _length(value: object, model: str, where: str = 'models') -> float:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not (math.isfinite(value) and value > 0)
    ):
        raise ValueError(f'{where}.{model}: lengths must be positive numbers in m, got {value!r}')
    return float(value)
