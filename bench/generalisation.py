"""Generalisation over four muscles: what ``pma-model fit`` prints against what the package serves
at each length it did not see.

For each map (the two shipped ones, and the two independent ones of
``../shared/data/independent-muscles/`` when present: fill branch and the spec beside it), with
``pma-model fit`` run in this process (``--model martens``, defaults otherwise; other options
after ``--``):

- in-sample: the default model's eq. 23 err on the whole map;
- printed: the nested held-out err per length from the fit's parameter file (``held_out``), and the
  last line's ``held-out worst``;
- served: for each length, ``pma-model fit`` on the map without it, then the served force of that
  fit (the parameter file loaded as ``evaluate`` and the nodes load it) on the length, eq. 23 in %
  of the whole map's max force.  Beyond the training lengths the served force depends on the rule
  for lengths outside the identified ones; each candidate rule is applied to the same fold fits:
  ``file`` (what the fit's file says), ``hold`` (the value at the nearest identified length),
  ``extrapolate`` (the model within the braid's shortest length .. L0, flagged EXTRAPOLATED), and
  per side (``long:X/short:Y``: toward L0 / below the shortest).
- interior worst: over the lengths between the longest and the shortest; edge worst: over those
  two.

Then a leave-one-muscle-out choice of the rule by the edge figure: for each muscle, the rule with
the lowest worst edge err over the other three, and that muscle's figure under it.

Usage: ``.venv/bin/python bench/generalisation.py [--quick] [--rules | --selection] [-- fit
options]``.  ``--quick``: the two shipped maps only; ``--rules``: also each model's rule (hold or
extrapolate, leave-one-muscle-out on the served edge err of ``fit --model <model>``) against the
rule served; ``--selection``: only the rule by which ``fit --model all`` chooses its default model,
leave-one-muscle-out (:func:`model_rules`).
Not a test.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
import re
import sys
import tempfile
import time

from _cli import run
import numpy as np

from pma_model_ros.core.files.param_file import load_muscle, read_parameters
from pma_model_ros.core.files.shipped_data import shipped_force_map
from pma_model_ros.core.identification.force_map import ForceMap, read_force_map_csv
from pma_model_ros.core.physics.models import extrapolates, TABLE3_MODELS

REPO = Path(__file__).resolve().parents[1]
INDEPENDENT = REPO.parent / 'shared' / 'data' / 'independent-muscles'
DATA = REPO / 'pma_model_ros' / 'core' / 'data'
SHIPPED = {
    'DMSP-20-300': ('DMSP-20-300', DATA / 'dmsp_20_300.yaml'),
    'DMSP-10-250': ('DMSP-10-250', DATA / 'dmsp_10_250.yaml'),
}
INDEPENDENT_MAPS = {
    'DMSP-20-274': (INDEPENDENT / 'dmsp20_274_fill.csv', INDEPENDENT / 'dmsp20_274.yaml'),
    'DMSP-10-382': (INDEPENDENT / 'dmsp10_382_fill.csv', INDEPENDENT / 'dmsp10_382.yaml'),
}
#: candidate rules beyond the identified lengths: (toward L0, below the shortest); None: as the
#: fit's parameter file says
RULES = {
    'file': (None, None),
    'hold': (False, False),
    'extrapolate': (True, True),
    'long:extrap/short:hold': (True, False),
    'long:hold/short:extrap': (False, True),
}
NO_TRADING = 0.5  #: [pp] the most any muscle's figure may worsen for a change to land


def write_map(path: Path, fmap: ForceMap) -> None:
    path.write_text(
        'pressure_pa,length_m,force_n\n'
        + ''.join(
            f'{float(p)!r},{float(L)!r},{float(F)!r}\n'
            for p, L, F in zip(fmap.pressure, fmap.length, fmap.force)
        )
    )


def last_line(text: str) -> str:
    return text.rstrip().splitlines()[-1]


def measure(name: str, csv: Path, spec: Path, options: list[str], tmp: Path) -> dict:
    """Every figure of one map (module docstring)."""
    fmap = read_force_map_csv(csv)
    out = tmp / 'fit.yaml'
    started = time.perf_counter()
    text = run(
        [
            'fit',
            '--data',
            str(csv),
            '--muscle',
            str(spec),
            *options,
            '--out',
            str(out),
            '--overwrite',
        ]
    )
    seconds = time.perf_counter() - started
    parameters = read_parameters(out)
    default = parameters['model']
    entry = parameters['models'][default]
    line = last_line(text).split('  -> ')[0]
    printed_worst = float(re.search(r'held-out worst ([0-9.]+) %', line).group(1))
    parts = re.search(r'between measured lengths ([0-9.]+) %, beyond them ([0-9.]+) %', line)
    lengths = fmap.lengths  # descending
    served = {rule: [] for rule in RULES}
    for k, length in enumerate(lengths):
        rest, at = fmap.subset(fmap.length != length), fmap.length == length
        write_map(tmp / 'rest.csv', rest)
        run(
            [
                'fit',
                '--data',
                str(tmp / 'rest.csv'),
                '--muscle',
                str(spec),
                *options,
                '--out',
                str(out),
                '--overwrite',
            ]
        )
        muscle = load_muscle(out)
        side = (
            'long'
            if length > rest.lengths.max()
            else 'short'
            if length < rest.lengths.min()
            else None
        )
        for rule, (long, short) in RULES.items():
            wide = {'long': long, 'short': short}.get(side)
            served_muscle = (
                muscle
                if wide is None
                else dataclasses.replace(
                    muscle, domain=dataclasses.replace(muscle.domain, extrapolates=wide)
                )
            )
            force = np.nan_to_num(served_muscle.force(fmap.pressure[at], fmap.length[at]).force)
            served[rule].append(100 * np.max(np.abs(fmap.force[at] - force)) / fmap.max_force)
    served = {rule: np.array(v) for rule, v in served.items()}
    printed = np.array(entry.get('held_out', {}).get('err', [np.nan] * lengths.size), float)
    return {
        'name': name,
        'lengths': lengths,
        'in_sample': float(entry['err']),
        'printed': printed,
        'printed_worst': printed_worst,
        # the last line's two parts (absent before it printed them: the file's nested errors')
        'printed_parts': tuple(map(float, parts.groups())) if parts else interior_edge(printed),
        'served': served,
        'line': line,
        'seconds': seconds,
    }


def interior_edge(errors: np.ndarray) -> tuple[float, float]:
    return float(np.max(errors[1:-1])), float(max(errors[0], errors[-1]))


def report(results: list[dict]) -> None:
    for r in results:
        print(
            f'\n{r["name"]}: nested held-out err [%] per length [m] '
            f'(in-sample {r["in_sample"]:.2f} %, fit {r["seconds"]:.1f} s)'
        )
        print(
            f'{"":<30}'
            + ''.join(f'{L:>8.3f}' for L in r['lengths'])
            + f'{"interior":>10}{"edge":>8}'
        )
        rows = {'fit prints': r['printed']} | {f'served {k}': v for k, v in r['served'].items()}
        for label, errors in rows.items():
            i, e = interior_edge(errors)
            print(f'{label:<30}' + ''.join(f'{v:>8.2f}' for v in errors) + f'{i:>10.2f}{e:>8.2f}')
        print(f'fit: {r["line"]}')
    print("\nfour-muscle table [%] (served: as the fit's parameter file serves it)")
    print(
        f'{"map":<14}{"in-sample":>10}{"interior":>10}{"edge":>8}{"fit prints":>12}'
        f'{"printed int.":>14}{"printed edge":>14}{"|printed-served|":>18}'
    )
    for r in results:
        i, e = interior_edge(r['served']['file'])
        pi, pe = r['printed_parts']
        gap = max(abs(r['printed_worst'] - max(i, e)), abs(pi - i), abs(pe - e))
        print(
            f'{r["name"]:<14}{r["in_sample"]:>10.2f}{i:>10.2f}{e:>8.2f}'
            f'{r["printed_worst"]:>12.2f}{pi:>14.2f}{pe:>14.2f}{gap:>18.2f}'
        )
    lomo(results)


def lomo(results: list[dict]) -> None:
    """Leave-one-muscle-out choice of the served rule by the worst edge err (module docstring)."""
    edge = {
        r['name']: {rule: interior_edge(v)[1] for rule, v in r['served'].items()} for r in results
    }
    rules = [rule for rule in RULES if rule != 'file']
    print('\nserved edge err [%] per rule beyond the identified lengths')
    print(f'{"map":<14}' + ''.join(f'{rule:>24}' for rule in rules))
    for name, row in edge.items():
        print(f'{name:<14}' + ''.join(f'{row[rule]:>24.2f}' for rule in rules))
    if len(results) < 2:
        return
    print('\nleave-one-muscle-out: the rule with the lowest worst edge err on the other muscles')
    print(f'{"judged":<14}{"chosen on the others":>26}{"its edge":>10}{"file":>8}')
    for name in edge:
        others = [n for n in edge if n != name]
        chosen = min(
            rules, key=lambda rule: (max(edge[n][rule] for n in others), rules.index(rule))
        )
        print(f'{name:<14}{chosen:>26}{edge[name][chosen]:>10.2f}{edge[name]["file"]:>8.2f}')
    for rule in rules:
        worse = [n for n in edge if edge[n][rule] > edge[n]['file'] + NO_TRADING]
        print(
            f"{rule}: worse than the file's rule by > {NO_TRADING} pp on "
            f'{", ".join(worse) if worse else "no muscle"}'
        )


def rules_by_model(maps: dict, tmp: Path) -> None:
    """The served rule of each model (:func:`~pma_model_ros.core.physics.models.extrapolates`)
    against its leave-one-muscle-out choice between holding and extrapolating, by the served edge
    err of ``fit --model <model>`` on every map.
    """
    print('\nserved edge err [%] per model: hold / extrapolate; the leave-one-muscle-out choice')
    print('for each map judged (chosen on the other maps); the rule the package serves')
    names = list(maps)
    print(
        f'{"model":<15}'
        + ''.join(f'{n:>17}' for n in names)
        + ''.join(f'{"LOMO " + n[5:]:>13}' for n in names)
        + f'{"served":>13}'
    )
    for model in (*TABLE3_MODELS, 'martens_end'):
        edge = {}
        for name, (csv, spec) in maps.items():
            r = measure(name, csv, spec, ['--model', model], tmp)
            edge[name] = {rule: interior_edge(r['served'][rule])[1] for rule in RULES}
        picks = []
        for name in names:
            others = [n for n in names if n != name] or names
            picks.append(
                min(('hold', 'extrapolate'), key=lambda rule: max(edge[n][rule] for n in others))
            )
        print(
            f'{model:<15}'
            + ''.join(f'{edge[n]["hold"]:>8.2f} /{edge[n]["extrapolate"]:>7.2f}' for n in names)
            + ''.join(f'{p:>13}' for p in picks)
            + f'{"extrapolate" if extrapolates(model) else "hold":>13}'
        )


def model_rules(maps: dict) -> None:
    """The rule by which ``fit --model all`` chooses the default model (``RULES`` of
    :mod:`pma_model_ros.core.identification.validation`), leave-one-muscle-out.

    Per map and rule: the model written, its in-sample err, the whole protocol's nested held-out
    figures (the model chosen again without each length by the rule: the honest figure of the
    rule) and the written model's own (what its file serves; a selection figure where the rule
    looked at it).  For each map judged, the rule chosen on the other maps: the lowest worst
    whole-protocol figure, rules within :data:`NO_TRADING` of it tied; a tie goes to the lowest
    sum of the written models' mean held-out err (every length counted once).
    """
    from pma_model_ros.core.files.user_files import read_spec_yaml
    from pma_model_ros.core.identification.calibration import Calibration
    from pma_model_ros.core.identification.selection import identify_all, MODEL_RULE
    from pma_model_ros.core.identification.validation import RULES as MODEL_RULES
    from pma_model_ros.core.physics.models import get_model

    models = tuple(get_model(m) for m in TABLE3_MODELS)
    rows = {}  # map -> rule -> figures
    for name, (csv, spec) in maps.items():
        found = identify_all(
            read_spec_yaml(spec),
            read_force_map_csv(csv),
            models,
            Calibration(),
            ('least_squares',),
        )
        rows[name] = {}
        for rule, (default, held_out, chosen) in found.by_rule.items():
            own = found.reports[default].nested
            rows[name][rule] = {
                'model': default,
                'in-sample': found.reports[default].shipped.err,
                'interior': interior_edge(held_out)[0],
                'edge': interior_edge(held_out)[1],
                'per fold': ' '.join(f'{n[:4]}x{chosen.count(n)}' for n in dict.fromkeys(chosen)),
                'own int.': interior_edge(own)[0],
                'own edge': interior_edge(own)[1],
                'own mean': float(np.nanmean(own)),
            }
    print(
        '\nfit --model all: the model written by each rule, its in-sample err, the whole '
        "protocol's held-out\nfigures [%] (interior, edge: the model chosen again without each "
        "length by the rule, per fold)\nand the written model's own (what its file serves)"
    )
    columns = ('in-sample', 'interior', 'edge', 'per fold', 'own int.', 'own edge', 'own mean')
    print(f'{"map":<13}{"rule":<19}{"model":<14}' + ''.join(f'{c:>{len(c) + 2}}' for c in columns))
    for name, by_rule in rows.items():
        for rule, row in by_rule.items():
            print(
                f'{name:<13}{rule:<19}{row["model"]:<14}'
                + ''.join(
                    f'{row[c]:>{len(c) + 2}}'
                    if isinstance(row[c], str)
                    else f'{row[c]:>{len(c) + 2}.2f}'
                    for c in columns
                )
            )
    if len(rows) < 2:
        return

    def worst(rule: str, names: list[str]) -> float:
        return max(max(rows[n][rule]['interior'], rows[n][rule]['edge']) for n in names)

    print(
        f'\nleave-one-muscle-out: the rule with the lowest worst whole-protocol figure on the '
        f'other maps\n(within {NO_TRADING} pp: tied; a tie to the lowest sum of own mean); '
        f'served: {MODEL_RULE}'
    )
    print(
        f'{"judged":<14}{"chosen on the others":>22}{"model":>15}{"in-sample":>10}'
        f'{"interior":>10}{"edge":>8}{"own int.":>10}{"own edge":>10}'
    )
    for name in rows:
        others = [n for n in rows if n != name]
        lowest = min(worst(r, others) for r in MODEL_RULES)
        tied = [r for r in MODEL_RULES if worst(r, others) <= lowest + NO_TRADING]
        rule = min(tied, key=lambda r: sum(rows[n][r]['own mean'] for n in others))
        row = rows[name][rule]
        print(
            f'{name:<14}{rule:>22}{row["model"]:>15}{row["in-sample"]:>10.2f}'
            f'{row["interior"]:>10.2f}{row["edge"]:>8.2f}{row["own int."]:>10.2f}'
            f'{row["own edge"]:>10.2f}'
        )
    for rule in MODEL_RULES:
        for base in MODEL_RULES:
            if base == rule:
                continue
            worse = [
                f'{n} ({what})'
                for n in rows
                for what in ('interior', 'edge')
                if rows[n][rule][what] > rows[n][base][what] + NO_TRADING
            ]
            print(
                f'{rule}: whole-protocol figures worse than {base} by > {NO_TRADING} pp on '
                + (', '.join(worse) if worse else 'no muscle')
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='the two shipped maps only')
    parser.add_argument(
        '--rules',
        action='store_true',
        help='also every model: its served rule against the leave-one-muscle-out choice',
    )
    parser.add_argument(
        '--selection',
        action='store_true',
        help='only the rule by which fit --model all chooses its default, leave-one-muscle-out',
    )
    argv = sys.argv[1:]
    options = argv[argv.index('--') + 1 :] if '--' in argv else ['--model', 'martens']
    args = parser.parse_args(argv[: argv.index('--')] if '--' in argv else argv)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        maps = {}
        for name, (muscle, spec) in SHIPPED.items():
            write_map(tmp / f'{name}.csv', shipped_force_map(muscle))
            maps[name] = (tmp / f'{name}.csv', spec)
        if args.quick:
            print('--quick: the two shipped maps only')
        elif not INDEPENDENT.is_dir():
            print(f'independent maps skipped: {INDEPENDENT.relative_to(REPO.parent)} is absent')
        else:
            maps |= INDEPENDENT_MAPS
        if args.selection:
            return model_rules(maps)
        for name, (csv, spec) in maps.items():
            results.append(measure(name, csv, spec, options, tmp))
        print(f'pma-model fit options: {" ".join(options) or "(defaults)"}')
        report(results)
        if args.rules:
            rules_by_model(maps, tmp)


if __name__ == '__main__':
    main()
