"""Instructions per cycle of model_node's input callbacks against the bare relay's, counted by
valgrind's callgrind: a count that does not move with the machine's load, where times do.

    scripts/netns-run .venv/bin/python bench/callback_instructions.py [--muscles 64] \
        [--cycles 1000] [--code DIR] [--quick]

A cycle is one pressure and one length message of N muscles (the inputs of
``bench/node_latency.py``'s pinger, as bytes, fresh: an hour's ``max_input_age``), each answered
and published (no subscriber).  model_node takes the bytes (its raw callbacks); the relay, as its
executor would, deserializes each with rclpy, then answers it (``node_latency.Relay``).  Each
responder runs twice under callgrind, with 0 and with ``--cycles`` cycles after 100 warm-up
cycles; per cycle = the difference of its main thread's instructions (``--separate-threads``: the
DDS threads' count moves with the run's wall time), divided by the cycles.  Counted, not timed:
caches and the executor are not in it (docs/performance.md: at 1 kHz the node's callbacks
cost 3-4 x their cost in a loop).  ``--code DIR`` counts model_node from another checkout
(before/after), the relay from this one.  About a minute per valgrind run, four per row.  Not a
pass/fail test.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import pickle
import re
import shutil
import subprocess
import sys
import tempfile

REPO = Path(__file__).resolve().parents[1]
WARMUP = 100  # cycles before the counted ones
STALE_NEVER = 3600.0  # [s] max_input_age: the inputs were stamped when written, minutes before


def inside(responder: str, muscles: int, params: Path, messages: Path, cycles: int) -> int:
    """Run ``cycles`` cycles of ``messages`` of ``muscles`` muscles (after the warm-up) through
    ``responder``, in this process (the one valgrind counts).
    """
    import rclpy
    from rclpy.serialization import deserialize_message

    inputs = pickle.loads(messages.read_bytes())[: WARMUP + cycles]
    rclpy.init(
        args=[
            '--ros-args',
            '-r',
            '__ns:=/count',
            '--params-file',
            str(params),
            '-p',
            f'max_input_age:={STALE_NEVER}',
            '--log-level',
            'warn',
        ]
    )
    try:
        if responder == 'model_node':
            from pma_model_ros.nodes.model_node import ModelNode

            node = ModelNode()
            handlers = (
                (lambda d: node._on_pressure(0, d), lambda d: node._on_state(0, d))
                if muscles == 1
                else (node._on_pressures, node._on_states)
            )
            for first, second in inputs:
                handlers[0](first)
                handlers[1](second)
            estimates = node.engine.counts(0).get('estimates', 0)
            if estimates < 2 * len(inputs) - 1:  # every input but the first
                print(f'inputs refused: {node.engine.counts(0)}', file=sys.stderr)
                return 1
        else:
            sys.path.insert(0, str(REPO / 'bench'))
            from node_latency import Relay
            from rclpy.parameter import Parameter

            node = Relay(parameter_overrides=[Parameter('muscles', value=muscles)])
            subscriptions = list(node.subscriptions)
            for cycle in inputs:
                for subscription, data in zip(subscriptions, cycle):
                    subscription.callback(deserialize_message(data, subscription.msg_type))
        node.destroy_node()
    finally:
        rclpy.shutdown()
    return 0


def write_inputs(muscles: int, folder: Path, cycles: int) -> tuple[Path, Path]:
    """(parameter file, pickled input bytes) of ``muscles`` muscles for ``cycles`` cycles."""
    sys.path.insert(0, str(REPO / 'bench'))
    import node_latency
    import rclpy

    params = (
        node_latency.SINGLE if muscles == 1 else node_latency.multi_muscle_file(muscles, folder)
    )
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        pinger = node_latency.Pinger('/unused', muscles, context)
        stamp = pinger.get_clock().now().nanoseconds
        inputs = [pinger.messages(k, stamp + k * 10**6) for k in range(WARMUP + cycles)]
        pinger.destroy_node()
    finally:
        rclpy.shutdown(context=context)
    messages = folder / f'inputs_{muscles}.pickle'
    messages.write_bytes(pickle.dumps(inputs))
    return params, messages


def counted(
    responder: str,
    muscles: int,
    params: Path,
    messages: Path,
    cycles: int,
    folder: Path,
    code: Path | None,
) -> int:
    """Instructions of the main thread of one counted run."""
    out = folder / f'{responder}_{cycles}'
    env = os.environ | {'OPENBLAS_NUM_THREADS': '1'}  # no BLAS threads spinning in the count
    if code is not None and responder == 'model_node':
        env['PYTHONPATH'] = str(code)
    command = [
        'valgrind',
        '--tool=callgrind',
        '--trace-children=yes',
        '--separate-threads=yes',
        f'--callgrind-out-file={out}.%p',
        sys.executable,
        __file__,
        '--inside',
        responder,
        str(muscles),
        str(params),
        str(messages),
        str(cycles),
    ]
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f'{responder}, {cycles} cycles:\n{done.stderr[-3000:]}')
    (main_thread,) = folder.glob(f'{out.name}.*-01')
    total = re.search(r'^summary: (\d+)', main_thread.read_text(), re.M)
    for file in folder.glob(f'{out.name}.*'):
        file.unlink()
    return int(total.group(1))


def main() -> int:
    if sys.argv[1:2] == ['--inside']:
        responder, muscles, params, messages, cycles = sys.argv[2:7]
        return inside(responder, int(muscles), Path(params), Path(messages), int(cycles))
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--muscles', type=int, nargs='+', default=[64], help='N (default 64)')
    parser.add_argument(
        '--cycles', type=int, default=1000, help='counted cycles per run (default 1000)'
    )
    parser.add_argument('--code', type=Path, help='count model_node from this checkout')
    parser.add_argument('--quick', action='store_true', help='200 cycles (bench/run --quick)')
    args = parser.parse_args()
    if args.quick:
        args.cycles = 200
    if shutil.which('valgrind') is None:
        raise SystemExit('callback_instructions: needs valgrind (Debian: apt install valgrind)')
    print(
        'main-thread instructions per cycle (one pressure and one length message, answered), '
        f'{args.cycles} cycles' + (f'; model_node from {args.code}' if args.code else '')
    )
    print(f'{"N":>3} {"model_node":>12} {"relay":>12} {"ratio":>7}')
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for n in args.muscles:
            params, messages = write_inputs(n, folder, args.cycles)
            per_cycle = {
                responder: (
                    counted(responder, n, params, messages, args.cycles, folder, args.code)
                    - counted(responder, n, params, messages, 0, folder, args.code)
                )
                / args.cycles
                for responder in ('model_node', 'relay')
            }
            model, relay = per_cycle['model_node'], per_cycle['relay']
            print(f'{n:>3} {model:>12,.0f} {relay:>12,.0f} {model / relay:>7.2f}', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
