"""`horus completion`: the bash completion script, made from the command's own parsers."""
from __future__ import annotations

from horus_cli.common import EXIT_OK

COMPLETION = """# bash completion for horus: `source <(horus completion)`
_horus() {
  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[1]} words
  if [ "$COMP_CWORD" -eq 1 ]; then
    words="%(commands)s"
  elif [[ "$cur" == -* ]] && [ "$COMP_CWORD" -ge 2 ] && \
       words=$(case "$prev/${COMP_WORDS[2]}" in
%(option_cases)s
               esac) && [ -n "$words" ]; then
    :  # an option of the command or action being typed
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
  elif [ "$prev" = remote ] && [ "${COMP_WORDS[2]}" = serve ]; then
    # horus-remote parses these itself (the command hands them on as they are).
    words="--listen --certs --name --allow --policy --namespace --insecure"
  elif [ "$prev" = remote ] && [ "${COMP_WORDS[2]}" = connect ]; then
    words="--certs --name --server-name --import --export --params --import-frames
           --export-frames --queue --call-timeout --namespace --insecure"
  elif [ "$prev" = launch ] && [ "$COMP_CWORD" -eq 3 ] && \
       { [ "${COMP_WORDS[2]}" = stop ] || [ "${COMP_WORDS[2]}" = restart ]; }; then
    # The processes of the one running launch (a launch's own name is the other choice).
    words=$(horus launch status --json 2>/dev/null | \
            /usr/bin/python3 -c 'import json,sys; print(" ".join(p["name"] for l in json.load(sys.stdin) for p in l["processes"]))' 2>/dev/null)
  elif [ "$prev" = param ] && [ "${COMP_WORDS[2]}" != load ]; then
    # The nodes with parameters, then (get, set, describe, watch) the node's parameters.
    if [ "$COMP_CWORD" -eq 3 ] || [ "${COMP_WORDS[2]}" = dump ]; then
      words=$(horus param list --names 2>/dev/null)
    elif [ "$COMP_CWORD" -eq 4 ] && [ "${COMP_WORDS[2]}" != list ]; then
      words=$(horus param list "${COMP_WORDS[3]}" --names 2>/dev/null)
    fi
  fi
  COMPREPLY=($(compgen -W "$words" -- "$cur"))
  if [ "$prev" = launch ] && [ "$COMP_CWORD" -eq 2 ]; then
    COMPREPLY+=($(compgen -f -X '!*.yaml' -- "$cur") $(compgen -d -- "$cur"))
  fi
}
complete -F _horus horus
"""


def _options(parser) -> str:
    """A parser's long options, help aside; empty for one that hands its arguments on as they
    are (its own program's options are written out in the script)."""
    return " ".join(sorted(option for option in parser._option_string_actions  # noqa: SLF001
                           if option.startswith("--") and option != "--help"))


def completion(args) -> int:
    parser = args.root_parser
    commands = parser._subparsers._group_actions[0].choices  # noqa: SLF001 (argparse has no API)
    cases, own_words, option_cases = [], [], []
    for name, sub in commands.items():
        if sub._subparsers is not None:  # noqa: SLF001
            actions = sub._subparsers._group_actions[0].choices  # noqa: SLF001
            cases.append(f'      {name}) words="{" ".join(actions)}" ;;')
            option_cases += [f'                 {name}/{action}) echo "{options}" ;;'
                             for action, action_parser in actions.items()
                             if (options := _options(action_parser))]
        else:
            if options := _options(sub):
                option_cases.append(f'                 {name}/*) echo "{options}" ;;')
            if sub.get_default("completion_words"):
                # A command that parses its own arguments (record: an action, or the topics
                # to record) names the words that may follow it.
                own_words.append(f'      {name}) words="{sub.get_default("completion_words")}" ;;')
    print(COMPLETION % {"commands": " ".join(commands), "cases": "\n".join(cases + own_words),
                        "option_cases": "\n".join(option_cases)}, end="")
    return EXIT_OK


def register(commands) -> None:
    sub = commands.command("completion", help="print the bash completion script",
                           description="Print the bash completion script: "
                                       "source <(horus completion)")
    sub.set_defaults(handler=completion)
