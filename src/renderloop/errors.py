"""The one exception type that means "the user gave us something we cannot use".

The CLI turns it into a single line on stderr and exit code 2; anything else that
escapes is a bug and keeps its traceback.
"""


class UserError(Exception):
    """Bad input: a config field, a file or a path. The message names it in one line."""
