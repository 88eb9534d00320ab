"""Safe reading of OpenSim XML documents, with element paths for error messages.

`read_document(path)` parses a ``.osim`` file with ``defusedxml`` (entity expansion and external
entities are refused: billion-laughs safe) and returns the root `Node`. A `Node` wraps an
element together with its XML path (``/OpenSimDocument/Model/JointSet/objects/
PinJoint[@name='knee']``) so that every `InputError` names the file, the element and the fix.
`parse_function(node)` turns an OpenSim function element into a `motion.osim.functions` object.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from ..errors import InputError
from .functions import (Constant, LinearFunction, MultiplierFunction, PiecewiseLinearFunction,
                        PolynomialFunction, SimmSpline)

__all__ = ["Node", "read_document", "parse_function", "FUNCTION_TAGS"]

FUNCTION_TAGS = ("Constant", "LinearFunction", "SimmSpline", "NaturalCubicSpline",
                 "PiecewiseLinearFunction", "MultiplierFunction", "PolynomialFunction")
_UNSUPPORTED_FUNCTIONS = ("GCVSpline", "StepFunction", "PiecewiseConstantFunction",
                          "ExpressionBasedFunction", "SmoothSegmentedFunction", "MultivariatePolynomialFunction")


class Node:
    """An XML element with its path in the document and the file it came from."""

    __slots__ = ("el", "path", "file")

    def __init__(self, el, path: str, file: str):
        self.el = el
        self.path = path
        self.file = file

    @property
    def tag(self) -> str:
        return self.el.tag

    @property
    def name(self) -> str:
        return (self.el.get("name") or "").strip()

    def _wrap(self, el) -> "Node":
        name = el.get("name")
        suffix = f"[@name='{name}']" if name else ""
        return Node(el, f"{self.path}/{el.tag}{suffix}", self.file)

    def child(self, tag: str) -> "Node | None":
        el = self.el.find(tag)
        return None if el is None else self._wrap(el)

    def children(self, tag: str | None = None) -> list:
        return [self._wrap(el) for el in self.el if isinstance(el.tag, str) and (tag is None or el.tag == tag)]

    def find(self, path: str) -> "Node | None":
        """First element at a slash path below this one (e.g. ``BodySet/objects``)."""
        node = self
        for part in path.split("/"):
            node = node.child(part)
            if node is None:
                return None
        return node

    def objects(self, set_tag: str) -> list:
        """Children of ``<set_tag><objects>`` (OpenSim's Set layout); [] if absent."""
        node = self.find(f"{set_tag}/objects")
        return [] if node is None else node.children()

    def error(self, problem: str, fix: str | None = None, where: str | None = None) -> InputError:
        return InputError(problem, file=self.file, where=where or self.path, fix=fix)

    def text(self, tag: str, default: str | None = None) -> str | None:
        el = self.el.find(tag)
        if el is None or el.text is None:
            return default
        return el.text.strip()

    def floats(self, tag: str, n: int | None = None, default=None) -> np.ndarray | None:
        txt = self.text(tag)
        if txt is None or txt == "":
            if default is None:
                return None
            return np.array(default, dtype=float)
        try:
            vals = np.array([float(v) for v in txt.split()], dtype=float)
        except ValueError:
            raise self.error(f"<{tag}> must hold numbers, got {txt[:60]!r}",
                             "write plain decimal numbers separated by spaces",
                             where=f"{self.path}/{tag}") from None
        if n is not None and len(vals) != n:
            raise self.error(f"<{tag}> must hold {n} numbers, got {len(vals)}",
                             f"write exactly {n} numbers", where=f"{self.path}/{tag}")
        if not np.all(np.isfinite(vals)):
            raise self.error(f"<{tag}> holds a non-finite number", "replace it with a finite value",
                             where=f"{self.path}/{tag}")
        return vals

    def float(self, tag: str, default: float) -> float:
        vals = self.floats(tag, default=None)
        if vals is None:
            return float(default)
        if len(vals) != 1:
            raise self.error(f"<{tag}> must hold one number, got {len(vals)}", "write one number",
                             where=f"{self.path}/{tag}")
        return float(vals[0])

    def bool(self, tag: str, default: bool) -> bool:
        txt = self.text(tag)
        if txt is None or txt == "":
            return default
        low = txt.lower()
        if low in ("true", "1"):
            return True
        if low in ("false", "0"):
            return False
        raise self.error(f"<{tag}> must be true or false, got {txt!r}", "write true or false",
                         where=f"{self.path}/{tag}")

    def names(self, tag: str) -> tuple:
        txt = self.text(tag)
        return tuple(txt.split()) if txt else ()


def _decode(data: bytes, file: str) -> str:
    """Bytes of an XML file as text: UTF-8, else Latin-1 (as OpenSim's own reader tolerates)."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    # the declaration's encoding is now meaningless: the text is already decoded
    return re.sub(r"^\s*<\?xml[^>]*\?>", "", text, count=1)


def read_document(path) -> Node:
    """Parse an OpenSim ``.osim`` document safely; return the ``<OpenSimDocument>`` node.

    Raises
    ------
    InputError
        Missing, empty, binary, malformed or truncated files, entity declarations
        (billion laughs, external entities), or XML that is not an OpenSim document.
    """
    import defusedxml.ElementTree as SafeET
    from defusedxml import DefusedXmlException
    from xml.etree.ElementTree import ParseError

    file = os.fspath(path)
    p = Path(file)
    if not p.exists():
        raise InputError("file not found", file=file, fix="check the path of the model file")
    if p.is_dir():
        raise InputError("is a directory, not a model file", file=file, fix="give the path of a .osim file")
    data = p.read_bytes()
    if not data.strip():
        raise InputError("the file is empty", file=file, fix="give a complete OpenSim .osim model file")
    if b"\x00" in data[:65536]:
        raise InputError("the file is binary, not XML", file=file,
                         fix="give an OpenSim .osim (XML text) model file")
    text = _decode(data, file)
    try:
        root = SafeET.fromstring(text)
    except DefusedXmlException as exc:
        raise InputError(f"the XML declares entities ({type(exc).__name__}); refused for safety",
                         file=file, where="DOCTYPE",
                         fix="remove the <!DOCTYPE>/<!ENTITY> declarations from the model") from None
    except ParseError as exc:
        line, col = getattr(exc, "position", (None, None))
        raise InputError(f"malformed or truncated XML ({exc.msg if hasattr(exc, 'msg') else exc})",
                         file=file, where=f"line {line}, column {col}" if line else None,
                         fix="repair the XML (is the file complete?) or re-export it from OpenSim") from None
    if root.tag != "OpenSimDocument":
        raise InputError(f"not an OpenSim document: the root element is <{root.tag}>",
                         file=file, where=f"/{root.tag}",
                         fix="give an OpenSim model file whose root element is <OpenSimDocument>")
    return Node(root, "/OpenSimDocument", file)


def _knots(node: Node):
    x = node.floats("x")
    y = node.floats("y")
    if x is None or y is None or len(x) != len(y) or len(x) < 1:
        raise node.error("a spline needs <x> and <y> of the same length",
                         "give matching <x> and <y> knot lists")
    if len(x) == 1:   # OpenSim pads a one-point spline to a constant over [x, x+1]
        x, y = np.array([x[0], x[0] + 1.0]), np.array([y[0], y[0]])
    if np.any(np.diff(x) < 0):
        raise node.error("the spline's <x> values are not increasing", "sort the knots by x")
    return x, y


def parse_function(node: Node):
    """An OpenSim function element (``<SimmSpline>``, ``<LinearFunction>`` ...) as an object."""
    tag = node.tag
    if tag == "Constant":
        return Constant(node.float("value", 0.0))
    if tag == "LinearFunction":
        c = node.floats("coefficients", default=[1.0, 0.0])
        if len(c) != 2:
            raise node.error(f"LinearFunction needs 2 coefficients (slope intercept), got {len(c)}",
                             "write <coefficients>slope intercept</coefficients>")
        return LinearFunction(float(c[0]), float(c[1]))
    if tag in ("SimmSpline", "NaturalCubicSpline"):
        return SimmSpline(*_knots(node))
    if tag == "PiecewiseLinearFunction":
        return PiecewiseLinearFunction(*_knots(node))
    if tag == "PolynomialFunction":
        c = node.floats("coefficients", default=[0.0])
        return PolynomialFunction(c)
    if tag == "MultiplierFunction":
        inner = function_child(node, "function")
        if inner is None:
            raise node.error("MultiplierFunction has no inner <function>", "add the function it scales")
        return MultiplierFunction(parse_function(inner), node.float("scale", 1.0))
    if tag in _UNSUPPORTED_FUNCTIONS:
        raise node.error(f"function type {tag} is not supported",
                         f"replace it by one of {', '.join(FUNCTION_TAGS)} (e.g. a SimmSpline through its values)")
    raise node.error(f"unknown function type <{tag}>",
                     f"use one of {', '.join(FUNCTION_TAGS)}")


def function_child(node: Node, wrapper: str) -> Node | None:
    """The function element held by ``node``: directly (4.x ``<SimmSpline name="function">``)
    or inside a ``<wrapper>`` element (3.x ``<function><SimmSpline>``)."""
    for ch in node.children():
        if ch.tag == wrapper:
            inner = ch.children()
            return inner[0] if inner else None
        if ch.tag in FUNCTION_TAGS or ch.tag in _UNSUPPORTED_FUNCTIONS:
            return ch
    return None
