"""The check a user can make of ``pma-model fit``'s held-out column, with the CLI alone.

For each measured length: ``pma-model fit`` on the map without it (same options), then
``pma-model evaluate --csv`` of that fit on the held-back length; its worst |error| in % of the
whole map's max force is that length's nested held-out error (a slack length has no force for
evaluate's eq. 23 and is skipped).  Prints the fit's column beside the check's.  Both judge the
force the fit's parameter file serves, as model_node does: at a held-out edge length a model that
does not extrapolate (``extrapolates: false``) is served at its nearest identified length, and the
check says so.

Usage: ``.venv/bin/python bench/held_out_check.py --data map.csv --muscle spec.yaml [options]``
with ``pma-model fit``'s options (default ``--model martens``).  Not a test
(``test/test_cli.py`` makes the same check on Table A2).
"""

from __future__ import annotations

import argparse
import contextlib
import io
from pathlib import Path
import tempfile

from pma_model_ros.cli.main import main as pma_model
from pma_model_ros.core.files.param_file import read_parameters
from pma_model_ros.core.identification.force_map import read_force_map_csv


def run(argv: list[str]) -> str:
    """``pma-model argv --overwrite`` (outputs are rewritten) in this process; its standard output
    (exit code 0 asserted).
    """
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = pma_model([*argv, '--overwrite'])
    if code != 0:
        raise SystemExit(f'pma-model {" ".join(argv)}: exit {code}')
    return out.getvalue()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--data', required=True)
    parser.add_argument('--muscle', required=True)
    args, fit_options = parser.parse_known_args()
    fit_options = fit_options or ['--model', 'martens']
    fmap = read_force_map_csv(args.data)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / 'fit.yaml'
        text = run(
            [
                'fit',
                '--data',
                args.data,
                '--muscle',
                args.muscle,
                *fit_options,
                '--out',
                str(out),
                '--overwrite',
            ]
        )
        print(text.rstrip())
        default = read_parameters(out)['model']
        printed = read_parameters(out)['models'][default]['held_out']['err']
        print(
            f'\ncheck of the held-out column of {default}: fit without each length, evaluate on it'
        )
        print(f'{"length [m]":>10}{"fit printed":>13}{"check":>9}')
        for length, shown in zip(fmap.lengths, printed):
            rest, held, points = (Path(tmp) / n for n in ('rest.csv', 'held.csv', 'points.csv'))
            for path, mask in ((rest, fmap.length != length), (held, fmap.length == length)):
                part = fmap.subset(mask)
                path.write_text(
                    'pressure_pa,length_m,force_n\n'
                    + ''.join(
                        f'{float(p)!r},{float(L)!r},{float(F)!r}\n'
                        for p, L, F in zip(part.pressure, part.length, part.force)
                    )
                )
            run(
                [
                    'fit',
                    '--data',
                    str(rest),
                    '--muscle',
                    args.muscle,
                    *fit_options,
                    '--out',
                    str(out),
                ]
            )
            if fmap.force[fmap.length == length].max() > 0:
                run(
                    [
                        'evaluate',
                        '--config',
                        str(out),
                        '--data',
                        str(held),
                        '--csv',
                        str(points),
                        '--overwrite',
                    ]
                )
                rows = [r.split(',') for r in points.read_text().splitlines()[1:]]
                errors = [abs(float(r[4])) for r in rows]
                check = f'{100 * max(errors) / fmap.max_force:>9.2f}'
                if any('LENGTH_OUT_OF_RANGE' in r[5] for r in rows):
                    check += '  (served at the nearest identified length: no extrapolation)'
            else:  # a slack length: no force for evaluate's eq. 23
                check = f'{"(slack)":>9}'
            print(f'{length:>10.4f}{shown:>13.2f}{check}')


if __name__ == '__main__':
    main()
