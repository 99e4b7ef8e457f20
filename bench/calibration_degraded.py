"""Identification on degraded maps: the shipped maps measured the way a user's are, with and
without calibration.

Usage: ``.venv/bin/python bench/calibration_degraded.py [--all-models | --nested | --write DIR]``
(docs/calibration.md). Not a test: it prints tables (``test/test_core_calibration.py`` asserts the
issue's targets on the same kind of degradation with another seed and another missing length).

Degradation of a shipped map (Martens & Boblan 2017, Tables A1/A2) with the paper's geometry as the
truth: the rest length L0 given ``dl`` wrong, the pressure sensor reading ``offset`` too high,
Gaussian force noise of ``noise`` x the max force (fixed seed, clipped at 0 N), and one interior
length missing.  Every error is eq. 23 against the *true* (noise-free) forces at the user's points
(sensor pressures), normalised by the true max force; ``data`` columns (in-sample, held-out) judge
against the noisy map itself, as the user sees it. Objectives and the default model are chosen as a
user's are: by held-out error on their own map.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml

from pma_model_ros.cli import describe_geometry
from pma_model_ros.core.calibration import Calibration, OFF
from pma_model_ros.core.force_map import ForceMap
from pma_model_ros.core.geometry import MuscleSpec
from pma_model_ros.core.identification import (
    cross_validate_fit,
    fit_best,
    identify_all,
    length_folds,
    max_error_percent,
    ModelReport,
)
from pma_model_ros.core.models import get_model, TABLE3_MODELS
from pma_model_ros.core.shipped_data import MAPPED_MUSCLES, shipped_force_map, shipped_spec


@dataclass(frozen=True)
class Degradation:
    dl: float = 0.0  #: error of the given rest length [m]
    offset: float = 0.0  #: pressure-sensor offset [Pa]: the sensor reads p + offset
    noise: float = 0.0  #: force noise, standard deviation / max force [-]
    missing: bool = False  #: drop the middle measured length
    seed: int = 0

    def label(self) -> str:
        if self == Degradation():
            return 'clean (paper geometry)'
        return (
            f'L0 {1e3 * self.dl:+.0f} mm, {self.offset / 1e3:+.0f} kPa, noise '
            f'{100 * self.noise:g} %' + (', a length missing' if self.missing else '')
        )


DEGRADED = tuple(Degradation(dl, 10e3, 0.01, True) for dl in (-0.004, +0.008, +0.004, -0.008))
SCENARIOS = (Degradation(), *DEGRADED)


def degrade(muscle: str, d: Degradation) -> tuple[MuscleSpec, ForceMap, np.ndarray]:
    """(the spec a user gives, the map they measure, the true forces at its points [N])."""
    spec, fmap = shipped_spec(muscle), shipped_force_map(muscle)
    keep = np.ones(fmap.force.size, bool)
    if d.missing:
        keep = fmap.length != fmap.lengths[fmap.lengths.size // 2]
    rng = np.random.default_rng(d.seed)
    noisy = (
        fmap.force + rng.normal(0.0, d.noise * fmap.max_force, fmap.force.size)
        if d.noise
        else fmap.force
    )
    user = ForceMap(
        fmap.pressure[keep] + d.offset, fmap.length[keep], np.maximum(noisy[keep], 0.0)
    )
    return replace(spec, nominal_length=spec.nominal_length + d.dl), user, fmap.force[keep]


def spec_given(muscle: str, d: Degradation) -> float:
    """The rest length L0 [m] the user gives."""
    return shipped_spec(muscle).nominal_length + d.dl


@dataclass(frozen=True)
class Outcome:
    #: identified as a user would (objective and default by held-out error on their map)
    report: ModelReport
    err_truth: float  #: in-sample eq. 23 against the true forces [%]
    cv_truth: float  #: worst leave-one-length-out eq. 23 against the true forces [%]


def identify(
    muscle: str, d: Degradation, calibration: Calibration, models: tuple[str, ...]
) -> tuple[dict, str]:
    """Every model of ``models`` identified on the degraded map: ({name: Outcome}, default by
    held-out error).
    """
    spec, user, truth = degrade(muscle, d)
    reports, default = identify_all(spec, user, tuple(get_model(m) for m in models), calibration)
    out = {}
    for name, rep in reports.items():
        fit = rep.shipped
        cv = cross_validate_fit(fit, user, (fit.objective,), truth)[fit.objective]
        out[name] = Outcome(
            rep,
            max_error_percent(truth, fit.force(user.pressure, user.length), truth.max()),
            float(cv.max()),
        )
    return out, default


def martens_table(muscle: str) -> None:
    truth = shipped_spec(muscle).nominal_length
    print(
        f'\n{muscle}, martens: err vs truth [%] (in-sample / worst held-out length); true L0 '
        f'{truth:.3f} m, '
        'true offset +10 kPa where degraded'
    )
    print(
        f'{"map given to the fit":<44}{"calibration":>12}{"in-sample":>10}{"held-out":>10}'
        f'{"data":>10}'
        f'{"data h-o":>10}  identified'
    )
    for d in SCENARIOS:
        for calibration in (OFF, Calibration()):
            outcome = identify(muscle, d, calibration, ('martens',))[0]['martens']
            rep = outcome.report
            geometry = (
                describe_geometry(rep.shipped, spec_given(muscle, d)) if calibration.any else ''
            )
            print(
                f'{d.label():<44}{"ON" if calibration.any else "off":>12}'
                f'{outcome.err_truth:>10.2f}'
                f'{outcome.cv_truth:>10.2f}{rep.shipped.err:>10.2f}{rep.cv_err:>10.2f}  {geometry}'
            )


def default_table(muscle: str) -> None:
    print(
        f'\n{muscle}: every Table 3 model, calibrated, on the degraded maps; default by held-out '
        f'error'
    )
    print(
        f'{"map given to the fit":<44}{"default":>10}{"in-sample":>10}{"held-out":>10}  identified'
    )
    for d in DEGRADED[:2]:
        outcomes, default = identify(muscle, d, Calibration(), TABLE3_MODELS)
        o = outcomes[default]
        geometry = describe_geometry(o.report.shipped, spec_given(muscle, d))
        print(f'{d.label():<44}{default:>10}{o.err_truth:>10.2f}{o.cv_truth:>10.2f}  {geometry}')


def nested_table(muscle: str) -> None:
    """Martens' worst held-out err when the whole calibrated identification (L0 search included) is
    re-run without the held-out length: no held-out length ever influences its own prediction.
    """
    print(
        f'\n{muscle}, martens calibrated, nested leave-one-length-out err vs truth [%] per '
        f'held-out length'
    )
    for d in SCENARIOS:
        spec, user, truth = degrade(muscle, d)
        errors = []
        for test in length_folds(user):
            fit = fit_best(
                get_model('martens'), spec, user.subset(~test), calibration=Calibration()
            )
            errors.append(
                max_error_percent(
                    truth[test], fit.force(user.pressure[test], user.length[test]), truth.max()
                )
            )
        print(
            f'{d.label():<44}'
            + ''.join(f'{e:>8.2f}' for e in errors)
            + f'   worst {max(errors):.2f}'
        )


def write(directory: Path) -> None:
    """The first degraded map of each muscle as a user's files: ``<muscle>_degraded.csv`` and
    ``.yaml`` (spec).
    """
    directory.mkdir(parents=True, exist_ok=True)
    for muscle in MAPPED_MUSCLES:
        spec, user, _ = degrade(muscle, DEGRADED[0])
        stem = directory / f'{muscle.lower().replace("-", "_")}_degraded'
        header = f'# {muscle} degraded: {DEGRADED[0].label()}\npressure_pa,length_m,force_n\n'
        stem.with_suffix('.csv').write_text(
            header
            + ''.join(
                f'{p:.6f},{L},{F:.6f}\n' for p, L, F in zip(user.pressure, user.length, user.force)
            )
        )
        stem.with_suffix('.yaml').write_text(yaml.safe_dump(spec.to_mapping(), sort_keys=False))
        print(f'wrote {stem}.csv and .yaml')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument(
        '--all-models', action='store_true', help='also the default model of every Table 3 model'
    )
    parser.add_argument(
        '--nested', action='store_true', help="only Martens' nested held-out err (slow)"
    )
    parser.add_argument(
        '--write',
        type=Path,
        help='only write the first degraded map of each muscle into this '
        'directory (for pma-model fit)',
    )
    args = parser.parse_args()
    if args.write:
        write(args.write)
        return
    if args.nested:
        for muscle in reversed(MAPPED_MUSCLES):
            nested_table(muscle)
        return
    for muscle in reversed(MAPPED_MUSCLES):
        martens_table(muscle)
    if args.all_models:
        for muscle in reversed(MAPPED_MUSCLES):
            default_table(muscle)


if __name__ == '__main__':
    main()
