"""Core speed: vectorised force and inverse of every model, scalar calls, closed form vs
root-finders.

Usage: ``.venv/bin/python bench/core_speed.py [--quick]`` (or ``bench/run``).  Not a test: it
prints tables.  Absolute times depend on the machine's load; the ratios, each taken within one row
of one run, are what to compare.  Every model is evaluated on the muscle of its shipped parameter
file (DMSP-10-250 for the paper's six models, DMSP-10-100 for ``sarosi_hysteresis``), at uniformly
random gauge pressures in [0, max_pressure] and lengths in the identified range.
"""

from __future__ import annotations

import argparse
from pathlib import Path
import time
from typing import Callable

import numpy as np
from scipy.optimize import brentq, newton

from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.files.shipped_data import SHIPPED_MUSCLES
from pma_model_ros.core.physics.models import force_raw
from pma_model_ros.core.physics.muscle_model import MuscleModel

CONFIG = Path(__file__).resolve().parents[1] / 'config'


def every_model() -> list[MuscleModel]:
    """One identified muscle per model, from the first shipped parameter file (DMSP-10-250 first)
    that has it.
    """
    muscles: dict[str, MuscleModel] = {}
    for stem in SHIPPED_MUSCLES.values():
        parameters = read_parameters(CONFIG / f'{stem}.yaml')
        for name in parameters['models']:
            muscles.setdefault(name, muscle_model(parameters, name))
    return sorted(muscles.values(), key=lambda m: (m.model.hysteresis, m.model.n_params))


def best_time(fn: Callable[[], object], repeat: int) -> float:
    """Shortest wall time of ``repeat`` calls [s] (the least disturbed by other load)."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def per_call(fn: Callable[[], object], calls: int, repeat: int) -> float:
    """Shortest mean time of one call over ``calls`` consecutive calls [s]."""
    return best_time(lambda: [fn() for _ in range(calls)], repeat) / calls


class Points:
    """Random operating points of one muscle: gauge pressure [Pa], length [m], length rate
    [m/s].
    """

    def __init__(self, muscle: MuscleModel, n: int, seed: int = 0) -> None:
        rng = np.random.default_rng(seed)
        self.pressure = rng.uniform(0, muscle.spec.max_pressure, n)
        self.length = rng.uniform(muscle.domain.length_min, muscle.domain.length_max, n)
        self.rate = rng.choice([-0.01, 0.01], n) if muscle.model.hysteresis else None
        self.branch = np.sign(self.rate) if muscle.model.hysteresis else 0.0

    def take(
        self, mask: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | float]:
        keep = lambda a: a[mask] if isinstance(a, np.ndarray) else a  # noqa: E731
        return self.pressure[mask], self.length[mask], keep(self.rate), keep(self.branch)


def vector_table(muscles: list[MuscleModel], n: int, repeat: int) -> None:
    print(
        f'\nVectorised, {n:.0e} points per call (best of {repeat}); Mpt/s = million points per '
        f'second.'
    )
    print(
        'ref = the plain numpy expression (a*p + b)*p + c on arrays of the same size '
        '(memory-bound);'
    )
    print('x ref = time of the call / time of ref, measured in the same row.')
    print(
        f'{"model":<18}{"muscle":<13}{"ref Mpt/s":>10}{"force Mpt/s":>13}{"x ref":>7}'
        f'{"inverse Mpt/s":>15}{"x ref":>7}'
    )
    for muscle in muscles:
        pts = Points(muscle, n)
        target = muscle.force(pts.pressure, pts.length, pts.rate).force
        t_ref = best_time(lambda: (2e-10 * pts.pressure + 3e-4) * pts.pressure - 50.0, repeat)
        t_force = best_time(lambda: muscle.force(pts.pressure, pts.length, pts.rate), repeat)
        t_inv = best_time(lambda: muscle.pressure(target, pts.length, pts.rate), repeat)
        print(
            f'{muscle.model.name:<18}{muscle.spec.name:<13}{n / t_ref / 1e6:>10.1f}'
            f'{n / t_force / 1e6:>13.2f}{t_force / t_ref:>7.1f}{n / t_inv / 1e6:>15.2f}'
            f'{t_inv / t_ref:>7.1f}'
        )


def scalar_table(muscles: list[MuscleModel], calls: int, repeat: int) -> None:
    print(f'\nOne scalar call (Python floats in, mean of {calls} calls, best of {repeat}).')
    print(
        'ref = one numpy ufunc call on Python floats, np.multiply(2.0, 3.0); x ref = call time / '
        'ref time.'
    )
    print(
        f'{"model":<18}{"muscle":<13}{"ref us":>8}{"force us":>10}{"x ref":>7}{"inverse us":>12}'
        f'{"x ref":>7}'
    )
    for muscle in muscles:
        rate = 0.01 if muscle.model.hysteresis else None
        p, L = (
            0.5 * muscle.spec.max_pressure,
            float(np.mean([muscle.domain.length_min, muscle.domain.length_max])),
        )
        t_ref = per_call(lambda: np.multiply(2.0, 3.0), calls, repeat)
        t_force = per_call(lambda: muscle.force(p, L, rate), calls, repeat)
        t_inv = per_call(lambda: muscle.pressure(100.0, L, rate), calls, repeat)
        print(
            f'{muscle.model.name:<18}{muscle.spec.name:<13}{t_ref * 1e6:>8.2f}'
            f'{t_force * 1e6:>10.1f}'
            f'{t_force / t_ref:>7.0f}{t_inv * 1e6:>12.1f}{t_inv / t_ref:>7.0f}'
        )


def root_finder_table(muscles: list[MuscleModel], n: int, n_brentq: int, repeat: int) -> None:
    print(
        "\nInverse: closed form (MuscleModel.pressure) vs scipy root-finders on the model's "
        'force_raw, on'
    )
    print(
        f'the same points: of {n:.0e} random points those with max(F_raw(0), 0) < F < '
        f'F_raw(max_pressure), so one'
    )
    print(
        'root in [0, max_pressure]. newton = scipy.optimize.newton on the whole array (vectorised '
        'secant from'
    )
    print(
        'max_pressure/2); brentq = scipy.optimize.brentq per point on [0, max_pressure], timed on '
        'the first'
    )
    print(
        f'{n_brentq} points and scaled per point. x closed = root-finder time per point / '
        f'closed-form time per'
    )
    print(
        'point. max|dp| = largest difference to the closed-form pressure [Pa]; not conv. = newton '
        'points that'
    )
    print('did not converge (excluded from max|dp|).')
    print(
        f'{"model":<18}{"points":>9}{"closed ns/pt":>13}{"newton ns/pt":>13}{"x closed":>9}'
        f'{"max|dp|":>9}'
        f'{"not conv.":>10}{"brentq us/pt":>13}{"x closed":>10}{"max|dp|":>9}'
    )
    for muscle in muscles:
        pts, (m, theta, spec, domain) = (
            Points(muscle, n),
            (muscle.model, muscle.theta, muscle.spec, muscle.domain),
        )
        p_max = spec.max_pressure
        force = muscle.force(pts.pressure, pts.length, pts.rate).raw
        at_zero = force_raw(m, theta, spec, domain, 0.0, pts.length, pts.branch)
        at_max = force_raw(m, theta, spec, domain, p_max, pts.length, pts.branch)
        one_root = (force > 0) & (at_zero < force) & (force < at_max)
        _, L, rate, branch = pts.take(one_root)
        F = force[one_root]
        closed = muscle.pressure(F, L, rate).pressure
        t_closed = best_time(lambda: muscle.pressure(F, L, rate), repeat) / F.size

        def vector_newton():
            return newton(
                lambda p: force_raw(m, theta, spec, domain, p, L, branch) - F,
                np.full(F.size, p_max / 2),
                maxiter=100,
                full_output=True,
            )

        t_newton = best_time(vector_newton, repeat) / F.size
        root, converged, _ = vector_newton()
        k = min(n_brentq, F.size)
        b = branch[:k] if isinstance(branch, np.ndarray) else np.zeros(k)

        def per_point_brentq():
            return np.array(
                [
                    brentq(
                        lambda p: float(force_raw(m, theta, spec, domain, p, L[i], b[i])) - F[i],
                        0.0,
                        p_max,
                    )
                    for i in range(k)
                ]
            )

        t_brentq = best_time(per_point_brentq, max(1, repeat // 2)) / k
        brent = per_point_brentq()
        print(
            f'{m.name:<18}{F.size:>9d}{t_closed * 1e9:>13.0f}{t_newton * 1e9:>13.0f}'
            f'{t_newton / t_closed:>9.1f}'
            f'{np.max(np.abs(root - closed)[converged], initial=0):>9.1e}'
            f'{np.count_nonzero(~converged):>10d}'
            f'{t_brentq * 1e6:>13.1f}{t_brentq / t_closed:>10.0f}'
            f'{np.max(np.abs(brent - closed[:k])):>9.1e}'
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        '--quick', action='store_true', help='1e5 instead of 1e6 points, fewer repeats'
    )
    args = parser.parse_args()
    n, repeat, calls, n_brentq = (
        (100_000, 3, 2000, 200) if args.quick else (1_000_000, 5, 10_000, 2000)
    )
    muscles = every_model()
    print('core speed: pma_model_ros.core MuscleModel.force / .pressure, every model')
    with np.errstate(all='ignore'):
        vector_table(muscles, n, repeat)
        scalar_table(muscles, calls, repeat)
        root_finder_table(muscles, n, n_brentq, repeat)


if __name__ == '__main__':
    main()
