"""The installed distribution's version (a module of its own: any layer may import it)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("impala-flow")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0"

__all__ = ["__version__"]
