"""`python3 -m horus_cli ARGS`: the `horus` command."""
import sys

from horus_cli.main import main

sys.exit(main())
