"""wavetomo/_version.py: the version of the C library this package was written for, whose major number the
loaded library must have (the soname's): WT_VERSION_MAJOR.MINOR.PATCH of include/wavetomo/version.h, the one
place it is defined. An installed package carries it in BUILT_VERSION (setup.py fills it in at build time);
the source tree's package reads the header two directories up.
"""
import pathlib
import re
from typing import Optional, Union

__all__ = ["VERSION", "header_version"]

BUILT_VERSION: Optional[str] = None


def header_version(path: Union[pathlib.Path, str]) -> str:
    """"MAJOR.MINOR.PATCH" from the WT_VERSION_* macros of a version.h."""
    text = pathlib.Path(path).read_text()
    parts = []
    for part in ("MAJOR", "MINOR", "PATCH"):
        m = re.search(r"^#define WT_VERSION_%s ([0-9]+)\b" % part, text, re.M)
        if m is None:
            raise RuntimeError("%s: no #define WT_VERSION_%s" % (path, part))
        parts.append(m.group(1))
    return ".".join(parts)


def _version() -> str:
    if BUILT_VERSION is not None:
        return BUILT_VERSION
    return header_version(pathlib.Path(__file__).resolve().parents[2] / "include" / "wavetomo" / "version.h")


VERSION: str = _version()
