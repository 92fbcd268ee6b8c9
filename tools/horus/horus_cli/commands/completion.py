"""`horus completion`: the bash completion script, made from the command's own parsers."""
from __future__ import annotations

from horus_cli.common import EXIT_OK

COMPLETION = """# bash completion for horus: `source <(horus completion)`
_horus() {
  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[1]} words
  if [ "$COMP_CWORD" -eq 1 ]; then
    words="%(commands)s"
  elif [ "$COMP_CWORD" -eq 2 ]; then
    case "$prev" in
%(cases)s
    esac
  elif [ "$COMP_CWORD" -eq 3 ] && [ "$prev" = topic ]; then
    words=$(horus topic list 2>/dev/null)
  elif [ "$COMP_CWORD" -eq 3 ] && [ "$prev" = node ]; then
    words=$(horus node list 2>/dev/null)
  elif [ "$COMP_CWORD" -eq 3 ] && [ "$prev" = service ]; then
    words=$(horus service list 2>/dev/null)
  elif [ "$prev" = param ] && [ "${COMP_WORDS[2]}" != load ]; then
    # The nodes with parameters, then (get, set, describe, watch) the node's parameters.
    if [ "$COMP_CWORD" -eq 3 ] || [ "${COMP_WORDS[2]}" = dump ]; then
      words=$(horus param list --names 2>/dev/null)
    elif [ "$COMP_CWORD" -eq 4 ] && [ "${COMP_WORDS[2]}" != list ]; then
      words=$(horus param list "${COMP_WORDS[3]}" --names 2>/dev/null)
    fi
  fi
  COMPREPLY=($(compgen -W "$words" -- "$cur"))
}
complete -F _horus horus
"""


def completion(args) -> int:
    parser = args.root_parser
    commands = parser._subparsers._group_actions[0].choices  # noqa: SLF001 (argparse has no API)
    cases, own_words = [], []
    for name, sub in commands.items():
        if sub._subparsers is not None:  # noqa: SLF001
            words = " ".join(sub._subparsers._group_actions[0].choices)  # noqa: SLF001
            cases.append(f'      {name}) words="{words}" ;;')
        elif sub.get_default("completion_words"):
            # A command that parses its own arguments (record: an action, or the topics to
            # record) names the words that may follow it.
            own_words.append(f'      {name}) words="{sub.get_default("completion_words")}" ;;')
    print(COMPLETION % {"commands": " ".join(commands), "cases": "\n".join(cases + own_words)},
          end="")
    return EXIT_OK


def register(commands) -> None:
    sub = commands.command("completion", help="print the bash completion script",
                           description="Print the bash completion script: "
                                       "source <(horus completion)")
    sub.set_defaults(handler=completion)
