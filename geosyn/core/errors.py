"""The error base of geosyn: every exception the library raises derives from it."""

from __future__ import annotations


class GeosynError(Exception):
    """Base class of every error geosyn raises on purpose.

    Catch this to tell bad input or a failed solve apart from a bug in geosyn itself.
    """


class InvalidArgument(GeosynError, ValueError):
    """An argument has the wrong shape, type, value or is not finite.

    The message names the argument, what was given and what is allowed.
    """
