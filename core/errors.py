"""Errors raised by `core` and `formats` for bad input.

The CLI turns every `InputError` into one clear line and a non-zero exit, so the
message must name the file or option, what was expected and what was found.
"""


class InputError(ValueError):
    """Bad user input: a file, an array or an option value that cannot be used."""
