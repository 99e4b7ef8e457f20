"""pma-model: reproduce the paper, identify muscles, judge fits on measured maps, evaluate force
and pressure, process bags, plot.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Sequence

from .bags import add_bag_commands
from .checks import check_outputs, CliError
from .identify import add_identify_commands
from .joint import add_joint_commands
from .parser import CliParser
from .plot import add_plot_command
from .query import add_query_commands


def build_parser() -> argparse.ArgumentParser:
    parser = CliParser(prog='pma-model', description=__doc__)
    sub = parser.add_subparsers(dest='command', required=True)
    add_identify_commands(sub)
    add_bag_commands(sub)
    add_joint_commands(sub)
    add_query_commands(sub)
    add_plot_command(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        check_outputs(args)
        args.func(args)
    except BrokenPipeError:  # the reader stopped early (`| head`): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # the Python docs' idiom
        return 0
    except (CliError, ValueError, OSError) as err:
        print(f'pma-model: error: {err}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C: outputs are written whole or not at all, workers ended
        print('pma-model: interrupted', file=sys.stderr)
        return 130  # 128 + SIGINT, as a shell reports it
    return 0
