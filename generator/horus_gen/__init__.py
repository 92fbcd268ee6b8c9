"""The HORUS schema compiler: lexer -> parser -> resolver (model, layout, identity) -> emitters.

In process: `describe_files` and `describe_schema_text` give the type description
(docs/type-description.md); errors are `SchemaCompileError`."""
from .api import SchemaCompileError, describe_files, describe_schema_text

__all__ = ["SchemaCompileError", "describe_files", "describe_schema_text"]
