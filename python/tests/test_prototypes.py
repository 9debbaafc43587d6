"""python/tests/test_prototypes.py: the ctypes layer (wavetomo/_lib.py) against the public C headers
(include/wavetomo/*.h). ctypes trusts whatever it is told: an int64_t return declared c_int, or a double
argument declared c_int, runs without complaint and gives wrong numbers. So every prototype the package
declares is compared with the header's declaration, parsed here; so are the two structs it mirrors and the
constants it copies (frame flags, sensor kinds, status codes). No library is needed: the headers and the
package's tables are read as text and data.

The parser knows the headers' style only: declarations end with ';' at brace depth 0, one function per
declaration, no macros in declarations.
"""
import ctypes
import pathlib
import re

import pytest

from wavetomo import _lib, errors

INCLUDE = pathlib.Path(__file__).resolve().parents[2] / "include" / "wavetomo"

# public functions the package does not wrap, on purpose: C callbacks (hooks) have no use from Python. A new
# public function must be wrapped or named here.
UNWRAPPED = {"wt_context_set_error_hook", "wt_context_set_log_hook", "wt_context_set_allocator"}

SCALARS = {"int": ctypes.c_int, "unsigned": ctypes.c_uint, "unsigned int": ctypes.c_uint, "int64_t": ctypes.c_int64,
           "int32_t": ctypes.c_int32, "double": ctypes.c_double, "float": ctypes.c_float, "size_t": ctypes.c_size_t,
           "char": ctypes.c_char}


def _strip(text):
    """The header without comments, preprocessor lines and the extern "C" wrapper."""
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)
    text = re.sub(r"//[^\n]*", " ", text)
    text = re.sub(r"^[ \t]*#(?:[^\n]*\\\n)*[^\n]*", " ", text, flags=re.M)
    return text.replace('extern "C" {', " ")


def _statements(text):
    """The declarations: text up to each ';' at brace depth 0 (a stray '}' of extern "C" is dropped)."""
    out, depth, cur = [], 0, []
    for ch in text:
        if ch == "{":
            depth += 1
        elif ch == "}":
            if depth == 0:
                continue
            depth -= 1
        if ch == ";" and depth == 0:
            out.append(" ".join("".join(cur).split()))
            cur = []
        else:
            cur.append(ch)
    return [s for s in out if s]


def _type(decl, name=None):
    """(base type without const, pointer depth, array length) of a declaration `const char *const *set`,
    with its name removed (the last identifier, unless it is the type itself)."""
    m = re.fullmatch(r"(.*?)(\[(\d+)\])?", decl.strip())
    decl, n = m.group(1).strip(), int(m.group(3)) if m.group(3) else None
    depth = decl.count("*")
    words = [w for w in re.split(r"[\s*]+", decl) if w and w != "const"]
    if name is None and len(words) > 1 and not (len(words) == 2 and words == ["unsigned", "int"]):
        words = words[:-1]  # the parameter's name
    return " ".join(words), depth, n


def parse_headers():
    """{function: (return type, [parameter types])}, {struct: [(field, type)]}, {constant: value} of the
    public headers, each type as _type() gives it."""
    functions, structs, constants = {}, {}, {}
    for h in sorted(INCLUDE.glob("*.h")):
        for s in _statements(_strip(h.read_text())):
            if s.startswith("enum"):
                for item in s[s.index("{") + 1:s.rindex("}")].split(","):
                    if item.strip():
                        k, v = item.split("=")
                        constants[k.strip()] = int(v)
            elif s.startswith("typedef struct") and "{" in s:
                name = s[s.rindex("}") + 1:].strip()
                fields = []
                for f in s[s.index("{") + 1:s.rindex("}")].split(";"):
                    if not f.strip():
                        continue
                    first, *more = f.split(",")
                    base, depth, n = _type(first)
                    fields.append((first.split()[-1].split("[")[0].lstrip("*"), (base, depth, n)))
                    fields += [(w.strip(), (base, depth, n)) for w in more]
                structs[name] = fields
            elif s.startswith("typedef"):
                continue  # an opaque type or a callback's type
            else:
                m = re.fullmatch(r"(.+?)\b(wt_\w+)\s*\((.*)\)", s)
                assert m, "%s: cannot read the declaration %r" % (h.name, s)
                ret = _type(m.group(1), name="")
                params = [p.strip() for p in m.group(3).split(",")]
                args = [] if params == ["void"] else [_type(p) for p in params]
                functions[m.group(2)] = (ret, args)
    return functions, structs, constants


FUNCTIONS, STRUCTS, CONSTANTS = parse_headers()
MIRRORS = {"wt_rtc_sensor": _lib.Sensor_c, "wt_rtc_dm": _lib.DM_c}


def expected(t):
    """The ctypes types a C type may be declared as: a scalar as itself, a string as c_char_p, an array of
    strings as POINTER(c_char_p), a pointer to a mirrored struct as POINTER(that Structure), any other
    pointer (an opaque handle, a numpy buffer's address) as c_void_p, a handle's out-parameter as
    POINTER(c_void_p); void as None."""
    base, depth, n = t
    if n is not None:
        return [SCALARS[base] * n]
    if depth == 0:
        return [None] if base == "void" else [SCALARS[base]]
    if base == "char":
        return [ctypes.c_char_p] if depth == 1 else [ctypes.POINTER(ctypes.c_char_p)]
    if depth == 1 and base in MIRRORS:
        return [ctypes.POINTER(MIRRORS[base])]
    if depth == 1:
        return [ctypes.c_void_p] + ([ctypes.POINTER(SCALARS[base])] if base in SCALARS else [])
    if depth == 2 and base.startswith("wt_"):
        return [ctypes.POINTER(ctypes.c_void_p)]
    raise AssertionError("no ctypes rule for %s%s" % (base, "*" * depth))


def test_parser_reads_the_headers():
    # a parser that silently read nothing would pass every test below
    assert FUNCTIONS["wt_rtc_frame"] == (("int", 0, None), [("wt_rtc", 1, None), ("double", 1, None),
                                                            ("int64_t", 0, None), ("double", 1, None),
                                                            ("unsigned", 0, None), ("double", 1, None),
                                                            ("int64_t", 0, None)])
    assert FUNCTIONS["wt_rtc_open"][1][4] == ("char", 2, None)
    assert FUNCTIONS["wt_version"] == (("char", 1, None), [])
    assert STRUCTS["wt_rtc_sensor"][0] == ("name", ("char", 0, 16))
    assert CONSTANTS["WT_ERR_INTERRUPTED"] == -8 and CONSTANTS["WT_RTC_SLOPES_OL"] == 2
    assert len(FUNCTIONS) > 30


@pytest.mark.parametrize("name", sorted(_lib._PROTOTYPES))
def test_prototype_matches_header(name):
    assert name in FUNCTIONS, "%s is declared in _lib.py but in no public header" % name
    restype, argtypes = _lib._PROTOTYPES[name]
    ret, args = FUNCTIONS[name]
    assert restype in expected(ret), "%s returns %s, declared %s" % (name, ret, restype)
    assert len(argtypes) == len(args), "%s takes %d arguments, declared %d" % (name, len(args), len(argtypes))
    for i, (a, t) in enumerate(zip(argtypes, args)):
        assert a in expected(t), "%s argument %d is %s, declared %s" % (name, i, t, a)


def test_every_public_function_is_wrapped():
    missing = set(FUNCTIONS) - set(_lib._PROTOTYPES) - UNWRAPPED
    assert not missing, "public functions without a ctypes prototype (wrap them, or list them in UNWRAPPED): %s" \
        % sorted(missing)
    assert not UNWRAPPED - set(FUNCTIONS), "UNWRAPPED names functions the headers no longer have"


@pytest.mark.parametrize("struct", sorted(MIRRORS))
def test_struct_mirrors_header(struct):
    fields = [(n, t) for n, t in MIRRORS[struct]._fields_]
    want = STRUCTS[struct]
    assert [n for n, _ in fields] == [n for n, _ in want], "%s: fields in another order or named otherwise" % struct
    for (n, t), (_, c) in zip(fields, want):
        assert t in expected(c), "%s.%s is %s, declared %s" % (struct, n, c, t)


def test_constants_match_headers():
    copies = {k: getattr(_lib, k) for k in ("WT_RTC_RAW", "WT_RTC_SLOPES_OL", "WT_RTC_LGS", "WT_RTC_NGS")}
    copies.update({k: v for k, v in vars(errors).items() if re.fullmatch(r"WT_(OK|WARN_\w+|ERR_\w+)", k)})
    status = {k for k in CONSTANTS if re.fullmatch(r"WT_(OK|WARN_\w+|ERR_\w+)", k)}
    assert status <= set(copies), "status codes missing from errors.py: %s" % sorted(status - set(copies))
    for k, v in copies.items():
        assert CONSTANTS.get(k) == v, "%s = %s in the package, %s in the headers" % (k, v, CONSTANTS.get(k))
