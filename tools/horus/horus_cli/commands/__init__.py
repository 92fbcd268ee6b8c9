"""The commands of `horus`, one module per noun, each with register(commands) adding its parsers
and the handlers they run. A command module imports the shared modules of horus_cli (common,
live, schemas), never another command module."""
