"""Identification on degraded maps: the shipped maps measured the way a user's are, with and
without calibration.

Usage: ``.venv/bin/python bench/calibration_degraded.py [--all-models | --write DIR]``
(docs/calibration.md). Not a test: it prints tables (``test/test_core_calibration.py`` asserts
bounds on the same kind of degradation with another seed and another missing length).

Degradation of a shipped map (Martens & Boblan 2017, Tables A1/A2) with the paper's geometry as the
truth: the rest length L0 given ``dl`` wrong, the pressure sensor reading ``offset`` too high,
Gaussian force noise of ``noise`` x the max force (fixed seed, clipped at 0 N), and one interior
length missing.  Every error is eq. 23 against the *true* (noise-free) forces at the user's points
(sensor pressures), normalised by the true max force.  Held-out errors are nested: the whole
identification (calibration and, with several models, the model choice, made on the user's noisy
map) re-run without each length.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml

from pma_model_ros.cli.identify import describe_geometry
from pma_model_ros.core.files.shipped_data import MAPPED_MUSCLES, shipped_force_map, shipped_spec
from pma_model_ros.core.identification.calibration import Calibration, OFF
from pma_model_ros.core.identification.force_map import ForceMap
from pma_model_ros.core.identification.protocols import max_error_percent
from pma_model_ros.core.identification.selection import Identification, identify_all
from pma_model_ros.core.physics.geometry import MuscleSpec
from pma_model_ros.core.physics.models import get_model, TABLE3_MODELS


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


DEGRADED = tuple(
    Degradation(dl, 10e3, 0.01, True) for dl in (-0.004, +0.008, +0.004, -0.008, -0.006)
)
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


def identify(
    muscle: str, d: Degradation, calibration: Calibration, models: tuple[str, ...]
) -> tuple[Identification, float]:
    """The models identified on the degraded map as a user would (least squares, default by
    held-out error), held-out errors against the truth; and the default's in-sample err against
    the truth [%].
    """
    spec, user, truth = degrade(muscle, d)
    found = identify_all(
        spec, user, tuple(get_model(m) for m in models), calibration, ('least_squares',), truth
    )
    fit = found.reports[found.default].shipped
    return found, max_error_percent(truth, fit.force(user.pressure, user.length), truth.max())


def table(muscle: str, models: tuple[str, ...]) -> None:
    """In-sample and nested held-out err vs the truth, calibration off and on, per scenario."""
    print(
        f'\n{muscle}, {"default of " + ", ".join(models) if len(models) > 1 else models[0]}: '
        f'err vs truth [%]: in-sample, nested held-out per length and worst; true L0 '
        f'{shipped_spec(muscle).nominal_length:.3f} m, true offset +10 kPa where degraded'
    )
    for d in SCENARIOS:
        for calibration in (OFF, Calibration()):
            found, in_sample = identify(muscle, d, calibration, models)
            fit = found.reports[found.default].shipped
            geometry = describe_geometry(fit, spec_given(muscle, d)) if calibration.any else ''
            print(
                f'{d.label():<44}{"ON" if calibration.any else "off":>4}{found.default:>9}'
                f'{in_sample:>7.2f} |'
                + ''.join(f'{e:>7.2f}' for e in found.held_out)
                + f' | worst {np.nanmax(found.held_out):6.2f}  {geometry}'
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
        '--write',
        type=Path,
        help='only write the first degraded map of each muscle into this '
        'directory (for pma-model fit)',
    )
    args = parser.parse_args()
    if args.write:
        write(args.write)
        return
    for muscle in reversed(MAPPED_MUSCLES):
        table(muscle, ('martens',))
    if args.all_models:
        for muscle in reversed(MAPPED_MUSCLES):
            table(muscle, TABLE3_MODELS)


if __name__ == '__main__':
    main()
