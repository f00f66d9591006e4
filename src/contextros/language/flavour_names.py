"""The layer language's flavours, by the name `--language` takes: a leaf module, so that the
command line lists them without importing the parser."""

LANGUAGES = ("python", "cpp")
