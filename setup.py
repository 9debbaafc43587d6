"""setup.py: what pyproject.toml cannot say declaratively.

- The version is the C library's: WT_VERSION_MAJOR.MINOR.PATCH of include/wavetomo/version.h, read by the
  package's own reader (python/wavetomo/_version.py) and written into the built copy of that file, so that an
  installed package knows it without the header.
- setuptools' scratch files (build/lib, *.egg-info) go to build/python, inside the C build's directory, and
  build/python/lib is emptied first: a module removed from the sources must not survive in a stale copy.
"""
import pathlib
import runpy
import shutil

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = pathlib.Path(__file__).resolve().parent
SCRATCH = ROOT / "build" / "python"
_version = runpy.run_path(str(ROOT / "python" / "wavetomo" / "_version.py"))
VERSION = _version["header_version"](ROOT / "include" / "wavetomo" / "version.h")


class BuildPy(build_py):
    """build_py that records VERSION in the built wavetomo/_version.py."""

    def run(self):
        super().run()
        built = pathlib.Path(self.build_lib) / "wavetomo" / "_version.py"
        text = built.read_text()
        line = "BUILT_VERSION: Optional[str] = None\n"
        if line not in text:
            raise RuntimeError("%s: no line %r to fill in" % (built, line))
        built.write_text(text.replace(line, "BUILT_VERSION: Optional[str] = %r\n" % VERSION))


shutil.rmtree(SCRATCH / "lib", ignore_errors=True)
SCRATCH.mkdir(parents=True, exist_ok=True)
setup(version=VERSION, cmdclass={"build_py": BuildPy},
      options={"build": {"build_base": str(SCRATCH)}, "egg_info": {"egg_base": str(SCRATCH)}})
