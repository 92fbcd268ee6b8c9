"""The HORUS schema compiler: lexer -> parser -> resolver (model, layout, identity) -> emitters."""
