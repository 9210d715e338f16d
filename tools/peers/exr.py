"""A minimal OpenEXR reader and writer (numpy and zlib only), enough for raygun's images and
the peer references: single-part scanline or single-level tiled files, HALF/FLOAT/UINT channels, compression NONE,
RLE (what raygun writes), ZIPS or ZIP (what `write_rgb` writes: FLOAT, 16-line zlib blocks).
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

MAGIC = 20000630
_LINES = {0: 1, 1: 1, 2: 1, 3: 16}
_DT = {0: np.dtype("<u4"), 1: np.dtype("<f2"), 2: np.dtype("<f4")}


def _unpredict(t: np.ndarray) -> bytes:
    """Undo OpenEXR's delta predictor and byte interleaving (shared by RLE and ZIP)."""
    t = t.astype(np.uint8)
    d = ((np.cumsum(np.concatenate(([t[0]], t[1:].astype(np.int64) - 128)))) & 0xFF).astype(
        np.uint8
    )
    half = (len(d) + 1) // 2
    out = np.empty(len(d), np.uint8)
    out[0::2] = d[:half]
    out[1::2] = d[half:]
    return out.tobytes()


def _predict(raw: bytes) -> bytes:
    b = np.frombuffer(raw, np.uint8)
    t = np.concatenate((b[0::2], b[1::2]))
    p = t.astype(np.int64)
    p[1:] = (t[1:].astype(np.int64) - t[:-1].astype(np.int64) + 128) & 0xFF
    return p.astype(np.uint8).tobytes()


def _rle_decode(data: bytes, expected: int) -> np.ndarray:
    out = bytearray()
    i = 0
    while i < len(data) and len(out) < expected:
        c = struct.unpack_from("b", data, i)[0]
        i += 1
        if c < 0:
            out += data[i : i + (-c)]
            i += -c
        else:
            out += data[i : i + 1] * (c + 1)
            i += 1
    return np.frombuffer(bytes(out), np.uint8)


def _read_attr_value(typ: str, v: bytes):
    if typ == "chlist":
        chans, i = [], 0
        while v[i] != 0:
            j = v.index(b"\0", i)
            name = v[i:j].decode()
            ptype, _plin, xs, ys = struct.unpack_from("<iB3xii", v, j + 1)
            chans.append((name, ptype, xs, ys))
            i = j + 1 + 16
        return chans
    if typ == "compression" or typ == "lineOrder":
        return v[0]
    if typ == "tiledesc":
        return struct.unpack_from("<IIB", v)
    if typ == "box2i":
        return struct.unpack("<iiii", v)
    return v


def read(path: str) -> dict[str, np.ndarray]:
    """Reads a scanline EXR: {channel name: (H, W) float32 array}."""
    with open(path, "rb") as f:
        data = f.read()
    magic, version = struct.unpack_from("<ii", data, 0)
    if magic != MAGIC:
        raise ValueError(f"{path}: not an OpenEXR file")
    tiled = bool(version & 0x200)
    if version & 0x1000:
        raise ValueError(f"{path}: multi-part EXR is not supported")
    off, attrs = 8, {}
    while data[off] != 0:
        j = data.index(b"\0", off)
        name = data[off:j].decode()
        k = data.index(b"\0", j + 1)
        typ = data[j + 1 : k].decode()
        (size,) = struct.unpack_from("<i", data, k + 1)
        attrs[name] = _read_attr_value(typ, data[k + 5 : k + 5 + size])
        off = k + 5 + size
    off += 1
    comp = attrs["compression"]
    if comp not in _LINES:
        raise ValueError(f"{path}: compression {comp} not supported (NONE, RLE, ZIPS, ZIP)")
    x0, y0, x1, y1 = attrs["dataWindow"]
    w, h = x1 - x0 + 1, y1 - y0 + 1
    chans = sorted(attrs["channels"])
    for c in chans:
        if c[2] != 1 or c[3] != 1:
            raise ValueError(f"{path}: subsampled channels are not supported")
    out = {c[0]: np.zeros((h, w), np.float32) for c in chans}

    def decode(block: bytes, rows: int, cols: int) -> bytes:
        expected = rows * sum(cols * _DT[c[1]].itemsize for c in chans)
        if len(block) == expected:
            return block
        if comp == 1:
            return _unpredict(_rle_decode(block, expected))
        if comp in (2, 3):
            return _unpredict(np.frombuffer(zlib.decompress(block), np.uint8))
        raise ValueError(f"{path}: bad chunk size")

    def scatter(raw: bytes, row0: int, rows: int, col0: int, cols: int) -> None:
        pos = 0
        for li in range(rows):
            for name, ptype, _, _ in chans:
                dt = _DT[ptype]
                out[name][row0 + li, col0 : col0 + cols] = np.frombuffer(raw, dt, cols, pos)
                pos += cols * dt.itemsize

    if tiled:
        tx, ty, mode = attrs["tiles"]
        if mode & 0xF != 0:
            raise ValueError(f"{path}: mipmapped/ripmapped EXR is not supported")
        nchunks = ((w + tx - 1) // tx) * ((h + ty - 1) // ty)
        offsets = struct.unpack_from(f"<{nchunks}Q", data, off)
        for o in offsets:
            dx, dy, _lx, _ly, size = struct.unpack_from("<iiiii", data, o)
            cols, rows = min(tx, w - dx * tx), min(ty, h - dy * ty)
            raw = decode(data[o + 20 : o + 20 + size], rows, cols)
            scatter(raw, dy * ty, rows, dx * tx, cols)
        return out
    nl = _LINES[comp]
    nchunks = (h + nl - 1) // nl
    offsets = struct.unpack_from(f"<{nchunks}Q", data, off)
    for o in offsets:
        y, size = struct.unpack_from("<ii", data, o)
        rows = min(nl, y1 - y + 1)
        raw = decode(data[o + 8 : o + 8 + size], rows, w)
        scatter(raw, y - y0, rows, 0, w)
    return out


def read_rgb(path: str) -> np.ndarray:
    """(H, W, 3) float32 linear RGB."""
    ch = read(path)
    return np.stack([ch["R"], ch["G"], ch["B"]], axis=-1)


def write_rgb(path: str, img: np.ndarray) -> None:
    """Writes (H, W, 3) as a FLOAT, ZIP-compressed scanline EXR (channels B, G, R)."""
    img = np.asarray(img, np.float32)
    h, w, _ = img.shape

    def attr(name, typ, value: bytes) -> bytes:
        return name.encode() + b"\0" + typ.encode() + b"\0" + struct.pack("<i", len(value)) + value

    chl = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for n in "BGR") + b"\0"
    header = (
        struct.pack("<ii", MAGIC, 2)
        + attr("channels", "chlist", chl)
        + attr("compression", "compression", b"\x03")
        + attr("dataWindow", "box2i", struct.pack("<iiii", 0, 0, w - 1, h - 1))
        + attr("displayWindow", "box2i", struct.pack("<iiii", 0, 0, w - 1, h - 1))
        + attr("lineOrder", "lineOrder", b"\x00")
        + attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
        + attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0))
        + attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
        + b"\0"
    )
    chunks = []
    for y in range(0, h, 16):
        rows = img[y : y + 16]
        raw = b"".join(
            np.ascontiguousarray(rows[r, :, c], "<f4").tobytes()
            for r in range(rows.shape[0])
            for c in (2, 1, 0)
        )
        z = zlib.compress(_predict(raw), 9)
        payload = z if len(z) < len(raw) else raw
        chunks.append(struct.pack("<ii", y, len(payload)) + payload)
    table_len = 8 * len(chunks)
    pos = len(header) + table_len
    offsets = []
    for c in chunks:
        offsets.append(pos)
        pos += len(c)
    with open(path, "wb") as f:
        f.write(header)
        f.write(struct.pack(f"<{len(offsets)}Q", *offsets))
        for c in chunks:
            f.write(c)
