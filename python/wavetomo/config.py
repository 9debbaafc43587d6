"""wavetomo/config.py: configuration text and overrides on the Python side.

The library reads and validates configurations (libconfig syntax, every key in docs/config.md); this file
only turns Python values into `--set key=value` overrides and reads the effective configuration text the
library returns (System.config, the "config" dataset of every output) into a flat dict of dotted keys.
"""
import numbers
import re
from typing import Any, Dict, Iterable, List, Mapping, Optional, Union

# set= of every entry point: {key: Python value} or "key=value" strings
Overrides = Optional[Union[Mapping[str, Any], Iterable[str]]]

__all__ = ["overrides", "parse"]


def _scalar(v):
    if isinstance(v, bool) or type(v).__name__ == "bool_":
        return "true" if v else "false"
    if isinstance(v, numbers.Integral):
        v = int(v)
        return "%dL" % v if not -2**31 <= v < 2**31 else "%d" % v
    if isinstance(v, numbers.Real):
        return repr(float(v))
    if isinstance(v, str):
        return '"%s"' % v.replace("\\", "\\\\").replace('"', '\\"')
    raise TypeError("override value %r: expected a bool, number, string or a list of them" % (v,))


def _value(v):
    if isinstance(v, (list, tuple)) or type(v).__name__ == "ndarray":
        items = list(v)
        # a libconfig array holds one type: integers among floats are written as floats
        if any(isinstance(x, numbers.Real) and not isinstance(x, numbers.Integral) for x in items):
            items = [float(x) for x in items]
        return "[" + ", ".join(_scalar(x) for x in items) + "]"
    return _scalar(v)


def overrides(set: Overrides = None) -> List[str]:
    """The `key=value` strings of `set`: a dict {key: value} (a Python bool, number, string, or a list of
    them: written in libconfig syntax, strings quoted) or an iterable of "key=value" strings (libconfig
    text as on the command line: `"dm.pitch_m=[0.5, 1.0, 1.0]"`)."""
    if set is None:
        return []
    if isinstance(set, str):
        raise TypeError("set=: give a dict or a list of \"key=value\" strings, not one string")
    if hasattr(set, "items"):
        return ["%s=%s" % (k, _value(v)) for k, v in set.items()]
    out = []
    for s in set:
        if not isinstance(s, str):
            raise TypeError("set=: %r is not a \"key=value\" string" % (s,))
        out.append(s)
    return out


_TOKEN = re.compile(r'''\s*(?:
      (?P<comment>\#[^\n]*|//[^\n]*|/\*.*?\*/)
    | (?P<string>"(?:[^"\\]|\\.)*")
    | (?P<number>[-+]?(?:0[xX][0-9a-fA-F]+|(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)L{0,2})
    | (?P<name>[A-Za-z*][-A-Za-z0-9_*]*)
    | (?P<punct>[=:;,{}\[\]()])
    )''', re.VERBOSE | re.DOTALL)


def _tokens(text):
    pos, n = 0, len(text)
    while pos < n:
        m = _TOKEN.match(text, pos)
        if not m or m.end() == pos:
            if text[pos:].strip() == "":
                return
            raise ValueError("configuration text: cannot read %r" % text[pos:pos + 20])
        pos = m.end()
        kind = m.lastgroup
        if kind != "comment":
            yield kind, m.group(kind)


class _Parser:
    def __init__(self, text):
        self.t = list(_tokens(text))
        self.i = 0

    def peek(self):
        return self.t[self.i] if self.i < len(self.t) else (None, None)

    def take(self, want=None):
        tok = self.peek()
        if tok[0] is None or (want is not None and tok[1] != want):
            raise ValueError("configuration text: expected %r, found %r" % (want, tok[1]))
        self.i += 1
        return tok

    def settings(self, out, prefix, end):
        while self.peek()[1] != end:
            kind, name = self.take()
            if kind != "name":
                raise ValueError("configuration text: expected a key, found %r" % name)
            if self.peek()[1] not in ("=", ":"):
                raise ValueError("configuration text: expected '=' after %s" % name)
            self.take()
            key = prefix + name
            if self.peek()[1] == "{":
                self.take("{")
                self.settings(out, key + ".", "}")
                self.take("}")
            else:
                out[key] = self.value()
            if self.peek()[1] in (";", ","):
                self.take()

    def value(self):
        kind, tok = self.take()
        if tok in ("[", "("):
            close = "]" if tok == "[" else ")"
            items = []
            while self.peek()[1] != close:
                if self.peek()[1] == "{":
                    self.take("{")
                    g = {}
                    self.settings(g, "", "}")
                    self.take("}")
                    items.append(g)
                else:
                    items.append(self.value())
                if self.peek()[1] == ",":
                    self.take()
            self.take(close)
            return items
        if kind == "string":
            s = tok[1:-1]
            while self.peek()[0] == "string":  # adjacent strings concatenate
                s += self.take()[1][1:-1]
            return re.sub(r'\\(.)', lambda m: {"n": "\n", "t": "\t"}.get(m.group(1), m.group(1)), s)
        if kind == "number":
            t = tok.rstrip("L")
            if t.lower().lstrip("+-").startswith("0x"):
                return int(t, 16)
            return float(t) if any(c in t for c in ".eE") else int(t)
        if kind == "name" and tok.lower() in ("true", "false"):
            return tok.lower() == "true"
        raise ValueError("configuration text: unexpected %r" % tok)


def parse(text: str) -> Dict[str, Any]:
    """A configuration's libconfig text as a flat dict {dotted key: value} (numbers, bools, strings,
    lists), e.g. parse(System(...).config)["loop.gain"]."""
    p = _Parser(text)
    out = {}
    p.settings(out, "", None)
    return out
