"""The command reference of the documentation, written from the parsers themselves.

:func:`command_reference` renders every subcommand of :func:`holoview.cli.build_parser`
(its help line, description, usage and every option by group, with choices and
defaults) as Markdown. The documentation site's build inserts it into its commands
page (``scripts/mkdocs_hooks.py``), so the reference cannot drift from the code: an
option added to a parser is in the next build.
"""

from __future__ import annotations

import argparse
import re

#: Width of the usage lines, characters.
USAGE_WIDTH = 88

#: Markdown's characters that help texts may hold literally.
_MARKDOWN = re.compile(r"([\\*_<>\[\]])")


def _escape(text: str) -> str:
    """Help text as Markdown: special characters escaped, code spans kept as they are."""
    pieces = text.split("`")
    return "`".join(p if i % 2 else _MARKDOWN.sub(r"\\\1", p) for i, p in enumerate(pieces))


def _usage(parser: argparse.ArgumentParser) -> str:
    """The parser's usage line(s), wrapped at :data:`USAGE_WIDTH` whatever the terminal."""
    formatter = argparse.HelpFormatter(parser.prog, width=USAGE_WIDTH)
    formatter.add_usage(parser.usage, parser._actions, parser._mutually_exclusive_groups)
    return formatter.format_help().strip()


def _invocation(action: argparse.Action) -> str:
    """``--name VALUE`` or ``-v, --verbose`` of an option, the metavar of a positional."""
    formatter = argparse.HelpFormatter("holoview", width=USAGE_WIDTH)
    if not action.option_strings:
        return action.metavar if isinstance(action.metavar, str) else action.dest
    if action.nargs == 0:
        return ", ".join(action.option_strings)
    value = formatter._format_args(action, action.dest.upper())
    return ", ".join(f"{option} {value}" for option in action.option_strings)


def _option_line(action: argparse.Action) -> str:
    """One bullet: the invocation in code, its help, its choices and default."""
    line = f"- `{_invocation(action)}`"
    if action.help:
        line += f": {_escape(action.help)}"
    default = action.default
    said = "default" in (action.help or "").lower()
    empty = default is None or default is False or default in ([], argparse.SUPPRESS)
    if not (said or empty or action.nargs == 0):
        line += f" (default: `{default}`)"
    return line


def _groups(parser: argparse.ArgumentParser) -> list[tuple[str, list[argparse.Action]]]:
    """``(title, actions)`` of each group with an action to show, in the parser's order."""
    groups = []
    for group in parser._action_groups:
        actions = [
            a
            for a in group._group_actions
            if a.help != argparse.SUPPRESS and not isinstance(a, argparse._HelpAction)
        ]
        if actions:
            title = group.title or "options"
            groups.append(("options" if title == "optional arguments" else title, actions))
    return groups


def _subcommands(
    parser: argparse.ArgumentParser,
) -> list[tuple[str, str, argparse.ArgumentParser]]:
    """``(name, help, parser)`` of every subcommand, in the order ``--help`` lists them."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help or "" for a in action._choices_actions}
            return [(name, helps.get(name, ""), sub) for name, sub in action.choices.items()]
    return []


def option_strings(parser: argparse.ArgumentParser) -> dict[str, list[str]]:
    """Every option string of every subcommand (``""``: the top level's), for tests."""
    found = {"": [s for a in parser._actions for s in a.option_strings]}
    for name, _, sub in _subcommands(parser):
        found[name] = [s for a in sub._actions for s in a.option_strings]
    return found


def command_reference(parser: argparse.ArgumentParser | None = None) -> str:
    """Return the Markdown reference of every ``holoview`` subcommand.

    Parameters
    ----------
    parser : ArgumentParser, optional
        The top-level parser (default :func:`holoview.cli.build_parser`'s).

    Returns
    -------
    str
        A ``##`` section for the options every command takes, then one per
        subcommand: its help line, description, usage, and its options by group.
    """
    if parser is None:
        from holoview.cli import build_parser

        parser = build_parser()
    lines = ["## Options of every command", "", f"```\n{_usage(parser)}\n```", ""]
    top = [a for a in parser._actions if a.option_strings and a.help != argparse.SUPPRESS]
    lines += [*(_option_line(a) for a in top if not isinstance(a, argparse._HelpAction)), ""]
    for name, summary, sub in _subcommands(parser):
        lines += [f"## holoview {name}", "", f"*{_escape(summary)}*", ""]
        if sub.description:
            lines += [_escape(sub.description), ""]
        lines += [f"```\n{_usage(sub)}\n```", ""]
        for title, actions in _groups(sub):
            lines += [f"**{_escape(title)}**", ""]
            lines += [*(_option_line(a) for a in actions), ""]
    return "\n".join(lines)
