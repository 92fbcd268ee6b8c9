"""The `horus` command as a package: main (the parser and dispatch), common (what every command
uses), live and schemas (what several commands read), and commands/, one module per noun.
`python3 -m horus_cli` runs it as the launcher bin/horus does."""
