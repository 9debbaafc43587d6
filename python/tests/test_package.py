"""python/tests/test_package.py: the package as installed, apart from the library's numbers. Importing it
needs no library (the library is loaded at the first call that needs it, which then says where it looked and
how to build or point to it); its version is the C header's; it ships py.typed; the public functions' type
hints resolve."""
import inspect
import os
import pathlib
import subprocess
import sys
import typing

import wavetomo
from conftest import REPO


def run_python(code, **env):
    """Run `python -c code` in a clean directory, importing the same package as this process, with the
    environment changed as given (None: unset)."""
    e = dict(os.environ)
    e["PYTHONPATH"] = os.pathsep.join([str(pathlib.Path(wavetomo.__file__).parents[1])] +
                                      ([e["PYTHONPATH"]] if e.get("PYTHONPATH") else []))
    for k, v in env.items():
        if v is None:
            e.pop(k, None)
        else:
            e[k] = v
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=e, cwd="/")


def test_import_without_library_then_clear_error(tmp_path):
    missing = str(tmp_path / "nowhere" / "libwavetomo.so.0")
    p = run_python("import wavetomo\n"
                   "print(wavetomo.__version__, wavetomo.parse_config('a = 1;'))\n"
                   "try:\n"
                   "    wavetomo.Reconstructor('x.cfg')\n"
                   "except wavetomo.LoadError as e:\n"
                   "    print('LoadError', isinstance(e, ImportError))\n"
                   "    print(e)\n", WAVETOMO_LIB=missing)
    assert p.returncode == 0, p.stderr
    lines = p.stdout.splitlines()
    assert lines[0] == "%s {'a': 1}" % wavetomo.__version__
    assert lines[1] == "LoadError True"
    text = "\n".join(lines[2:])
    assert missing + " (no such file)" in text and "WAVETOMO_LIB" in text and "make" in text


def test_version_is_the_header_s():
    h = (REPO / "include" / "wavetomo" / "version.h").read_text()
    from wavetomo import _version
    assert wavetomo.__version__ == _version.header_version(REPO / "include" / "wavetomo" / "version.h")
    assert "#define WT_VERSION_MAJOR %s\n" % wavetomo.__version__.split(".")[0] in h


def test_typed_and_hints_resolve():
    assert (pathlib.Path(wavetomo.__file__).parent / "py.typed").exists()
    for name in wavetomo.__all__:
        obj = getattr(wavetomo, name)
        targets = [obj] if inspect.isfunction(obj) else [f for f in vars(obj).values() if inspect.isfunction(f)] \
            if inspect.isclass(obj) else []
        for f in targets:
            typing.get_type_hints(f)  # raises on a misspelt or unimported name in an annotation
