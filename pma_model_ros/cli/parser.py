"""The argparse parser of every ``pma-model`` command (:class:`CliParser`).

An option that takes a value is refused when given twice (argparse keeps the last one without a
word); an unknown option is named, with the closest option of its own subcommand, under that
subcommand's usage (argparse would first say a required option is missing, or name it under the
top-level usage). Options are not abbreviated (``allow_abbrev=False``): one spelling each, so
that a command line keeps its meaning when an option is added, and the hint names the option a
prefix stands for.
"""

from __future__ import annotations

import argparse
from typing import Sequence

from ..core.hints import did_you_mean

#: Namespace attribute holding, while one parser parses, the options given so far.
_GIVEN = '_given_options'


class StoreOnce(argparse._StoreAction):
    """argparse's ``store``, refusing a second value for the same destination."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault(_GIVEN, {})
        if option_string is not None:
            if self.dest in given:
                first, value = given[self.dest]
                raise argparse.ArgumentError(
                    self,
                    f'given twice ({first} {_text(value)}, then {option_string} '
                    f'{_text(values)}); give it once',
                )
            given[self.dest] = (option_string, values)
        super().__call__(parser, namespace, values, option_string)


def _is_number(arg: str) -> bool:
    """Whether ``arg`` is a number (a negative value, not an option)."""
    try:
        float(arg)
    except ValueError:
        return False
    return True


def _text(values: object) -> str:
    return ' '.join(map(str, values)) if isinstance(values, list) else str(values)


class CliParser(argparse.ArgumentParser):
    """An ArgumentParser (subcommands are made of the same class) with :class:`StoreOnce` as
    ``store``, no abbreviations, and unknown options named by the subcommand that got them.
    """

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault('allow_abbrev', False)
        super().__init__(*args, **kwargs)
        self.register('action', None, StoreOnce)
        self.register('action', 'store', StoreOnce)

    def parse_known_args(self, args: Sequence[str] | None = None, namespace=None):
        leaf = self._subparsers is None  # a subcommand: every remaining argument is its own
        if leaf and args is not None:
            self._refuse_unknown_options(list(args))
        namespace, extras = super().parse_known_args(args, namespace)
        namespace.__dict__.pop(_GIVEN, None)
        if leaf and extras:
            self.error(f'unrecognized arguments: {" ".join(extras)}')
        return namespace, extras

    def _refuse_unknown_options(self, args: list[str]) -> None:
        """``error`` naming the first option of ``args`` this parser does not know (argparse's
        rule of what is an option: a leading '-', no space; not a number).
        """
        for arg in args:
            if arg == '--':
                return
            name = arg.split('=', 1)[0]
            if (
                not arg.startswith('-')
                or arg == '-'
                or ' ' in arg
                or name in self._option_string_actions
                or arg[:2] in self._option_string_actions
                or _is_number(arg)
            ):
                continue
            options = [o[2:] for o in self._option_string_actions if o.startswith('--')]
            prefixed = [o for o in options if o.startswith(name[2:])] if name[:2] == '--' else []
            hint = f" (did you mean '--{prefixed[0]}'?)" if len(prefixed) == 1 else ''
            close = did_you_mean(name.lstrip('-'), options).replace("'", "'--", 1)
            hint = hint or close or f' ({self.prog} -h lists its options)'
            self.error(f'unknown option {name}{hint}')
