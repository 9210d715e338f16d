"""A minimal glTF 2.0 / GLB reader and GLB writer (numpy only).

Reads what raygun's loader reads (src/scene/load.rs): the default scene's node tree with
matrix or TRS transforms, triangle primitives (indexed or not) with POSITION, NORMAL and
TEXCOORD_0 (float, or normalized integer accessors), materials, perspective cameras, and
embedded (bufferView) or external images. Sparse accessors are not needed by raygun's test
scenes and raise an error.
"""

from __future__ import annotations

import base64
import json
import os
import struct

import numpy as np

GLB_MAGIC = 0x46546C67
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942

_COMPONENT = {
    5120: np.int8,
    5121: np.uint8,
    5122: np.int16,
    5123: np.uint16,
    5125: np.uint32,
    5126: np.float32,
}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


class Gltf:
    """A parsed glTF document: `json` (dict) and its buffers (list of bytes)."""

    def __init__(self, doc: dict, buffers: list[bytes], base_dir: str):
        self.json = doc
        self.buffers = buffers
        self.base_dir = base_dir

    @classmethod
    def load(cls, path: str) -> "Gltf":
        with open(path, "rb") as f:
            data = f.read()
        base = os.path.dirname(os.path.abspath(path))
        bin_chunk = None
        if data[:4] == struct.pack("<I", GLB_MAGIC):
            _, version, length = struct.unpack_from("<III", data, 0)
            if version != 2:
                raise ValueError(f"{path}: GLB version {version}, expected 2")
            off, doc = 12, None
            while off < length:
                clen, ctype = struct.unpack_from("<II", data, off)
                chunk = data[off + 8 : off + 8 + clen]
                if ctype == CHUNK_JSON:
                    doc = json.loads(chunk.decode("utf-8"))
                elif ctype == CHUNK_BIN and bin_chunk is None:
                    bin_chunk = chunk
                off += 8 + clen
            if doc is None:
                raise ValueError(f"{path}: GLB without a JSON chunk")
        else:
            doc = json.loads(data.decode("utf-8"))
        buffers = []
        for i, b in enumerate(doc.get("buffers", [])):
            uri = b.get("uri")
            if uri is None:
                if bin_chunk is None:
                    raise ValueError(f"{path}: buffer {i} has no uri and there is no BIN chunk")
                buffers.append(bin_chunk)
            elif uri.startswith("data:"):
                buffers.append(base64.b64decode(uri.split(",", 1)[1]))
            else:
                with open(os.path.join(base, uri), "rb") as f:
                    buffers.append(f.read())
        return cls(doc, buffers, base)

    def view_bytes(self, index: int) -> bytes:
        v = self.json["bufferViews"][index]
        buf = self.buffers[v["buffer"]]
        off = v.get("byteOffset", 0)
        return buf[off : off + v["byteLength"]]

    def accessor(self, index: int) -> np.ndarray:
        """The accessor's elements as an (count, ncomp) array (float32 for float or normalized
        data, the integer type otherwise)."""
        a = self.json["accessors"][index]
        if "sparse" in a:
            raise NotImplementedError("sparse accessors")
        dtype = np.dtype(_COMPONENT[a["componentType"]])
        n = _NCOMP[a["type"]]
        count = a["count"]
        if "bufferView" not in a:
            out = np.zeros((count, n), dtype)
        else:
            v = self.json["bufferViews"][a["bufferView"]]
            buf = self.buffers[v["buffer"]]
            base = v.get("byteOffset", 0) + a.get("byteOffset", 0)
            elem = dtype.itemsize * n
            stride = v.get("byteStride", elem) or elem
            if stride == elem:
                out = np.frombuffer(buf, dtype, count * n, base).reshape(count, n)
            else:
                raw = np.frombuffer(buf, np.uint8, (count - 1) * stride + elem, base)
                rows = np.lib.stride_tricks.as_strided(raw, (count, elem), (stride, 1))
                out = np.ascontiguousarray(rows).view(dtype).reshape(count, n)
        if a.get("normalized", False):
            info = np.iinfo(dtype)
            out = out.astype(np.float32) / info.max
            if info.min < 0:
                out = np.maximum(out, -1.0)
        elif dtype.kind == "f":
            out = out.astype(np.float32)
        return out

    def image_bytes(self, index: int) -> bytes:
        im = self.json["images"][index]
        if "bufferView" in im:
            return self.view_bytes(im["bufferView"])
        uri = im["uri"]
        if uri.startswith("data:"):
            return base64.b64decode(uri.split(",", 1)[1])
        with open(os.path.join(self.base_dir, uri), "rb") as f:
            return f.read()


def node_matrix(node: dict) -> np.ndarray:
    """A node's local transform (4×4, column vectors)."""
    if "matrix" in node:
        return np.array(node["matrix"], np.float64).reshape(4, 4).T
    t = np.array(node.get("translation", [0, 0, 0]), np.float64)
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    s = np.array(node.get("scale", [1, 1, 1]), np.float64)
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    m = np.eye(4)
    m[:3, :3] = r * s[None, :]
    m[:3, 3] = t
    return m


class GlbWriter:
    """Builds a GLB file: add arrays as accessors, then `write(path, doc)`."""

    def __init__(self):
        self.bin = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def _view(self, data: bytes, target: int | None = None) -> int:
        while len(self.bin) % 4:
            self.bin.append(0)
        v = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if target is not None:
            v["target"] = target
        self.bin.extend(data)
        self.views.append(v)
        return len(self.views) - 1

    def add(self, arr: np.ndarray, indices: bool = False) -> int:
        arr = np.ascontiguousarray(arr, np.uint32 if indices else np.float32)
        if indices:
            arr = arr.reshape(-1)
            acc = {"componentType": 5125, "type": "SCALAR", "count": int(arr.size)}
            view = self._view(arr.tobytes(), 34963)
        else:
            n = arr.shape[1]
            acc = {
                "componentType": 5126,
                "type": {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}[n],
                "count": int(arr.shape[0]),
            }
            if n == 3:
                acc["min"] = [float(v) for v in arr.min(0)]
                acc["max"] = [float(v) for v in arr.max(0)]
            view = self._view(arr.tobytes(), 34962)
        acc["bufferView"] = view
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def add_image(self, png: bytes) -> int:
        """A bufferView holding encoded image bytes."""
        return self._view(png)

    def write(self, path: str, doc: dict) -> None:
        doc = dict(doc)
        doc["buffers"] = [{"byteLength": len(self.bin)}]
        doc["bufferViews"] = self.views
        doc["accessors"] = self.accessors
        js = json.dumps(doc, separators=(",", ":")).encode("utf-8")
        js += b" " * (-len(js) % 4)
        binc = bytes(self.bin) + b"\0" * (-len(self.bin) % 4)
        total = 12 + 8 + len(js) + 8 + len(binc)
        with open(path, "wb") as f:
            f.write(struct.pack("<III", GLB_MAGIC, 2, total))
            f.write(struct.pack("<II", len(js), CHUNK_JSON))
            f.write(js)
            f.write(struct.pack("<II", len(binc), CHUNK_BIN))
            f.write(binc)
