"""The one exception type users see: what was expected, what came, what to do."""


class SatsightError(Exception):
    """An error caused by the user's input or environment, with a message that teaches.

    The command line prints the message (no traceback) and exits with status 2.
    """
