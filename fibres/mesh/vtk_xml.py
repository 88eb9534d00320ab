"""The XML half of `fibres.mesh.vtk_reader`: ``.vtp`` (PolyData) and ``.vtu`` (UnstructuredGrid).

Every data mode VTK writes (VTK User's Guide, "XML File Formats"): ``ascii``, inline ``binary``
(base64; VTK encodes the header of compressed data as its own padded chunk) and ``appended``
(raw or base64), header ``UInt32``/``UInt64``, little or big endian, uncompressed or compressed
with ``vtkZLibDataCompressor`` (zlib) or ``vtkLZMADataCompressor`` (lzma); several pieces are
concatenated. The XML before the appended data is parsed with defusedxml (no entities). Every
declared size is checked against the bytes present, and decompression is capped at the declared
block size, before anything is allocated; every problem is a `_Bad` (one line).
"""
from __future__ import annotations

import base64
import binascii
import re
import zlib

import numpy as np

from .vtk_reader import _Bad, _cells_from_offsets, _check_bytes, _count, _unstructured

__all__ = ["read_xml"]

_XML_TYPES = {"Int8": "i1", "UInt8": "u1", "Int16": "i2", "UInt16": "u2", "Int32": "i4",
              "UInt32": "u4", "Int64": "i8", "UInt64": "u8", "Float32": "f4", "Float64": "f8"}


def read_xml(data):
    """(points (V, 3) float64, cell groups) of a VTK XML file's bytes (`vtk_reader._triangles`)."""
    from xml.etree.ElementTree import ParseError

    import defusedxml.ElementTree as SafeET
    from defusedxml import DefusedXmlException

    cut = data.find(b"<AppendedData")
    appended, encoding = b"", None
    text = data
    if cut >= 0:
        tag_end = data.find(b">", cut)
        if tag_end < 0:
            raise _Bad("the AppendedData tag is not closed")
        m = re.search(rb'encoding\s*=\s*"([^"]*)"', data[cut:tag_end])
        encoding = m.group(1).decode("latin-1") if m else "raw"
        under = data.find(b"_", tag_end)
        if under < 0:
            raise _Bad("the appended data has no '_' start mark")
        appended = data[under + 1:]
        text = data[:cut] + b"</VTKFile>"
    try:
        root = SafeET.fromstring(text)
    except DefusedXmlException:
        raise _Bad("the XML declares entities; refused for safety") from None
    except ParseError as exc:
        raise _Bad(f"malformed or truncated XML ({exc})") from None
    if root.tag != "VTKFile":
        raise _Bad(f"the root element is <{root.tag}>, not <VTKFile>")
    kind = root.get("type")
    if kind not in ("PolyData", "UnstructuredGrid"):
        raise _Bad(f"VTKFile type {kind!r} is not a surface (PolyData or UnstructuredGrid)")
    if encoding is not None and encoding not in ("raw", "base64"):
        raise _Bad(f"unknown appended data encoding {encoding!r}")
    ctx = _XmlCtx(root, appended, encoding)
    grid = root.find(kind)
    if grid is None:
        raise _Bad(f"no <{kind}> element")
    all_points, cells, offset = [], [], 0
    for k, piece in enumerate(grid.findall("Piece")):
        what = f"Piece {k}"
        n = _count(piece.get("NumberOfPoints", "0"), f"{what} NumberOfPoints")
        pts_el = piece.find("Points/DataArray")
        if pts_el is None:
            if n:
                raise _Bad(f"{what}: no Points")
            pts = np.zeros((0, 3))
        else:
            pts = ctx.array(pts_el, f"{what} Points")
            if pts.size != 3 * n:
                raise _Bad(f"{what}: {pts.size} point values for {n} points")
            pts = pts.astype(np.float64).reshape(n, 3)
        if kind == "PolyData":
            for tag, group in (("Polys", "poly"), ("Strips", "strip")):
                el = piece.find(tag)
                declared = _count(piece.get(f"NumberOf{tag}", "0"), f"{what} NumberOf{tag}")
                if el is None:
                    if declared:
                        raise _Bad(f"{what}: NumberOf{tag}={declared} but no <{tag}>")
                    continue
                starts, sizes, conn = ctx.cells(el, n, f"{what} {tag}")
                if starts.size != declared:
                    raise _Bad(f"{what}: {starts.size} {tag.lower()} for NumberOf{tag}={declared}")
                cells.append((group, starts, sizes, conn + offset))
        else:
            el = piece.find("Cells")
            declared = _count(piece.get("NumberOfCells", "0"), f"{what} NumberOfCells")
            if el is not None:
                starts, sizes, conn = ctx.cells(el, n, f"{what} Cells")
                if starts.size != declared:
                    raise _Bad(f"{what}: {starts.size} cells for NumberOfCells={declared}")
                types = ctx.array(ctx.named(el, "types", f"{what} Cells"), f"{what} Cells types")
                for group in _unstructured(starts, sizes, conn, types, f"{what} Cells"):
                    cells.append(group[:3] + (group[3] + offset,))
            elif declared:
                raise _Bad(f"{what}: NumberOfCells={declared} but no <Cells>")
        all_points.append(pts)
        offset += n
    points = np.concatenate(all_points) if all_points else np.zeros((0, 3))
    return points, cells


class _XmlCtx:
    """Decodes the DataArrays of one VTK XML file (module docstring: every data mode)."""

    def __init__(self, root, appended, encoding):
        order = root.get("byte_order", "LittleEndian")
        if order not in ("LittleEndian", "BigEndian"):
            raise _Bad(f"unknown byte_order {order!r}")
        self.order = "<" if order == "LittleEndian" else ">"
        header = root.get("header_type", "UInt32")
        if header not in ("UInt32", "UInt64"):
            raise _Bad(f"unknown header_type {header!r}")
        self.header = np.dtype(self.order + ("u4" if header == "UInt32" else "u8"))
        comp = root.get("compressor")
        if comp not in (None, "", "vtkZLibDataCompressor", "vtkLZMADataCompressor"):
            raise _Bad(f"compressor {comp!r} is not supported (use zlib, LZMA or none)")
        self.compressor = comp or None
        self.appended, self.encoding = appended, encoding
        offs = []
        for el in root.iter("DataArray"):
            if el.get("format") == "appended":
                offs.append(_count(el.get("offset", "0"), "DataArray offset"))
        self.offsets = sorted(set(offs))

    def named(self, parent, name, what):
        for el in parent.findall("DataArray"):
            if el.get("Name") == name:
                return el
        raise _Bad(f"{what}: no DataArray named {name!r}")

    def cells(self, el, n_points, what):
        offsets = self.array(self.named(el, "offsets", what), f"{what} offsets")
        conn = self.array(self.named(el, "connectivity", what), f"{what} connectivity")
        if offsets.dtype.kind not in "iu" or conn.dtype.kind not in "iu":
            raise _Bad(f"{what}: offsets and connectivity must be integers")
        return _cells_from_offsets(offsets, conn, n_points, what, leading_zero=False)

    def array(self, el, what):
        vtype = el.get("type")
        if vtype not in _XML_TYPES:
            raise _Bad(f"{what}: unsupported type {vtype!r}")
        dtype = np.dtype(self.order + _XML_TYPES[vtype])
        fmt = el.get("format", "ascii")
        if fmt == "ascii":
            parts = (el.text or "").split()
            _check_bytes(len(parts) * dtype.itemsize, what)
            try:
                return np.array(parts, dtype=np.str_).astype(dtype.newbyteorder("="))
            except (ValueError, OverflowError):
                raise _Bad(f"{what}: a value is not a number of type {vtype}") from None
        if fmt == "binary":
            raw = _base64(el.text or "", what)
        elif fmt == "appended":
            if self.encoding is None:
                raise _Bad(f"{what}: format='appended' but the file has no AppendedData")
            start = _count(el.get("offset", "0"), f"{what} offset")
            if self.encoding == "base64":
                later = [o for o in self.offsets if o > start]
                chunk = self.appended[start:later[0] if later else len(self.appended)]
                end = chunk.find(b"<")
                raw = _base64(chunk[:end] if end >= 0 else chunk, what)
            else:
                raw = memoryview(self.appended)[start:]
        else:
            raise _Bad(f"{what}: unknown format {fmt!r}")
        payload = self._payload(raw, what)
        if len(payload) % dtype.itemsize:
            raise _Bad(f"{what}: {len(payload)} bytes is not a whole number of {vtype} values")
        return np.frombuffer(payload, dtype=dtype)

    def _ints(self, raw, start, n, what):
        size = self.header.itemsize
        if start + n * size > len(raw):
            raise _Bad(f"{what}: the data ends inside its header")
        return [int(v) for v in np.frombuffer(raw, dtype=self.header, count=n, offset=start)]

    def _payload(self, raw, what):
        """The uncompressed bytes of one array (header + data or header + compressed blocks)."""
        size = self.header.itemsize
        if self.compressor is None:
            (n_bytes,) = self._ints(raw, 0, 1, what)
            _check_bytes(n_bytes, what)
            if size + n_bytes > len(raw):
                raise _Bad(f"{what}: {n_bytes} bytes declared, {len(raw) - size} present (truncated?)")
            return bytes(raw[size:size + n_bytes])
        n_blocks, block, last = self._ints(raw, 0, 3, what)
        if n_blocks == 0:
            return b""
        _check_bytes(n_blocks * size, what)
        sizes = self._ints(raw, 3 * size, n_blocks, what)
        total = (n_blocks - 1) * block + (last or block)
        _check_bytes(total, what)
        pos = (3 + n_blocks) * size
        if pos + sum(sizes) > len(raw):
            raise _Bad(f"{what}: compressed blocks run past the end of the data (truncated?)")
        out = []
        for k, c in enumerate(sizes):                       # loop over blocks (32 KiB each)
            want = last if (k == n_blocks - 1 and last) else block
            piece = bytes(raw[pos:pos + c])
            pos += c
            try:
                if self.compressor == "vtkZLibDataCompressor":
                    got = zlib.decompressobj().decompress(piece, want)
                else:
                    import lzma

                    dec = lzma.LZMADecompressor()
                    got = dec.decompress(piece, max_length=want)
            except Exception:  # noqa: BLE001 - zlib.error, lzma.LZMAError: damaged data
                raise _Bad(f"{what}: compressed block {k} is damaged") from None
            if len(got) != want:
                raise _Bad(f"{what}: compressed block {k} gives {len(got)} bytes, {want} declared")
            out.append(got)
        return b"".join(out)


def _base64(text, what) -> bytes:
    """Decode base64 that may be several separately padded chunks (VTK writes the header of
    compressed data as its own chunk)."""
    if isinstance(text, str):
        text = text.encode("latin-1", "replace")
    clean = re.sub(rb"\s+", b"", bytes(text))
    chunks = re.findall(rb"[A-Za-z0-9+/]+=*|=+", clean)
    if b"".join(chunks) != clean:
        raise _Bad(f"{what}: characters that are not base64")
    out = []
    for chunk in chunks:
        if len(chunk) % 4:
            raise _Bad(f"{what}: base64 data of a length that is not a multiple of 4 (truncated?)")
        try:
            out.append(base64.b64decode(chunk, validate=True))
        except binascii.Error:
            raise _Bad(f"{what}: damaged base64 data") from None
    return b"".join(out)
