"""The exceptions acdf raises.

Every one derives from :class:`Error`, and most also from the built-in
exception a Python user would catch for the same cause, so ``except
FileNotFoundError`` and ``except ValueError`` work as expected. The message
is the one line the ``acdf`` command prints for the same failure.
"""

from __future__ import annotations

__all__ = [
    "Error",
    "NotFoundError",
    "IoError",
    "UnknownNameError",
    "MaterialError",
    "IncompatibleError",
    "InvalidArgumentError",
    "ShapeError",
    "DTypeError",
    "SamplerFileError",
    "EnvMapError",
    "TargetNotReachedError",
]


class Error(Exception):
    """Base class of every exception acdf raises."""


class NotFoundError(Error, FileNotFoundError):
    """A material, weight or sampler file that does not exist (``errno`` and
    ``filename`` are set as for the built-in)."""


class IoError(Error, OSError):
    """Reading or writing a file failed for another reason than its absence."""


class UnknownNameError(Error, ValueError):
    """A material, sampler or simplifier name acdf does not know; the message
    lists the known ones."""


class MaterialError(Error, ValueError):
    """A material file that exists but cannot be read (malformed, truncated)."""


class IncompatibleError(Error, ValueError):
    """A sampler that cannot be used with this material (``rgl`` without a
    ``.bsdf`` file, a sampler file built for another material, saving a
    sampler without tables)."""


class InvalidArgumentError(Error, ValueError):
    """A parameter out of its domain (resolution, tolerance, cosine mix,
    angles, sample counts)."""


class ShapeError(InvalidArgumentError):
    """An array of the wrong shape: directions are (3,) or (N, 3), uniform
    pairs (2,) or (N, 2), and the N of the arguments must agree."""


class DTypeError(Error, TypeError):
    """An array that is neither float32 nor float64."""


class SamplerFileError(Error, ValueError):
    """A sampler file that is damaged, of a newer format, or of a kind no
    sampler reads."""


class EnvMapError(Error, ValueError):
    """An environment map that exists but cannot be used: not decodable, not
    a latitude-longitude map (twice as wide as high), or with NaN, infinite
    or negative texels (``EnvMap.load(path, repair=True)`` sets those to 0)."""


class TargetNotReachedError(Error, ValueError):
    """No tolerance of the adaptive sampler reaches the target efficiency
    asked for; the message says the best found."""
