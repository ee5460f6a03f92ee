"""Errors the command line reports without a traceback."""


class UsageError(Exception):
    """Bad input found before any long work starts; printed as one clear message."""
