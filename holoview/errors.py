"""The exceptions holoview raises for problems a user can fix.

Every subpackage derives its errors from :class:`HoloviewError`, so the command
line can turn any of them into one line on stderr and exit status 2, and the GUI
can show it in the window while the rest keeps running. Programming errors are
not ``HoloviewError`` and keep their tracebacks.
"""


class HoloviewError(Exception):
    """A problem the user can fix: bad input, a missing device, a broken file."""


class InputError(HoloviewError, ValueError):
    """An argument, frame or file content is invalid; the message names it."""
