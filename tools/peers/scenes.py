"""raygun glTF scenes -> Mitsuba 3 scene dicts, and the peer suite's generated scenes.

`load(path)` reads a glTF/GLB the way raygun's loader does (src/scene/load.rs): the default
scene's node tree, node transforms baked into world space (a mirroring transform swaps two
vertices so the front side keeps its counter-clockwise winding), triangle primitives with
NORMAL (inverse-transpose transformed) and TEXCOORD_0, glTF materials (baseColorFactor and
texture, metallicFactor, roughnessFactor, emissiveFactor x KHR_materials_emissive_strength,
KHR_materials_specular's specularFactor, doubleSided) and perspective cameras.

`mitsuba_dict(scene, ...)` builds the equivalent Mitsuba 3 scene (call `mi.set_variant`
first). The mapping, and where it is exact:

* Every BSDF is wrapped in `twosided`: raygun shades both sides of every triangle (it flips
  the geometric and shading normals towards the viewer, src/trace/path.rs).
* metallic 0, specularFactor 0: `diffuse` (reflectance = base colour). Exact: raygun's BSDF is
  then exactly Lambertian (src/trace/shading.rs).
* metallic 1: `roughconductor`, distribution `ggx`, alpha = roughness^2 (clamped to raygun's
  MIN_ALPHA = 1e-3), no visible-normal restriction on the value (sampling only). Fresnel: glTF
  uses Schlick with F0 = base colour; Mitsuba's conductor uses the exact complex-IOR Fresnel,
  so per channel we pick (eta, k) with exactly that F0 and the least cosine-weighted squared
  difference to Schlick over all angles (`conductor_fit`; for F0 >= 0.5 the largest difference
  in F is < 0.013 and the hemispherical mean differs < 0.4 %; F0 = 1 is exact: eta 0, k 1).
  Masking: glTF's height-correlated Smith V vs Mitsuba's separable G1(i)G1(o); they differ by
  the Lambda(i)Lambda(o) term, small except at grazing angles and high roughness.
  A textured metallic base colour uses eta = 0, k = 1 (F = 1) times the texture as
  `specular_reflectance` (no Schlick rise towards grazing).
* metallic 0, specularFactor s > 0 (glTF's dielectric layer): `roughplastic` (ggx, alpha as
  above, int_ior from F0 = 0.04 s, i.e. 1.5 for s = 1, nonlinear false). NOT equivalent: glTF
  mixes Lambert and GGX with the Schlick weight (1 - F(v.h)) on the diffuse lobe and no
  internal scattering, Mitsuba's plastic weights the diffuse by (1 - F(i))(1 - F(o)) / eta^2
  and adds internal reflections (1 / (1 - R_d F_dr)), with the exact dielectric Fresnel.
* 0 < metallic < 1: `blendbsdf` with weight = metallic of the two above (glTF's BSDF is that
  linear blend: f = (1 - m) f_dielectric + m f_metal, with raygun's (1 - m)(1 - F_d) diffuse).
* Emission (emissiveFactor x strength, linear radiance): an `area` emitter on the mesh.
  Mitsuba's area light emits from the front side only (the side the counter-clockwise winding
  and the glTF normal face). doubleSided false: that one-sided emitter (the back face still
  reflects through the two-sided BSDF but neither emits nor is sampled - raygun's planned
  behaviour). doubleSided true: a second copy of the emitter with reversed winding and
  normals, moved back along the face normal by `EMITTER_GAP` x the scene's diagonal (1e-5),
  so each side of the sheet is the front of one copy and hides the other copy's back.
* Camera: `perspective`, fov = yfov (fov_axis y; the image's aspect decides the horizontal
  field as in raygun), look_at from the node's position along its -Z with its +Y up, pinhole;
  `box` reconstruction filter (raygun jitters uniformly inside the pixel); `hdrfilm` RGB.
* Environment: constant radiance -> `constant`; an equirectangular map -> `envmap`. raygun's
  texel (col, row) covers u = 0.5 + atan2(d.x, -d.z) / 2pi, v = acos(d.y) / pi, piecewise
  constant (nearest texel), row 0 = zenith (src/scene/mod.rs, src/trace/shading.rs).
  Mitsuba's envmap (identity to_world) puts column j's sample at u_m = atan2(d.x, -d.z) / 2pi
  = (j + 0.5) / W, i.e. half a turn from raygun's, and row i's sample at v = i / (H - 1)
  (rows from pole to pole), interpolating bilinearly. So the Mitsuba map is raygun's
  resampled on Mitsuba's grid, `ENV_UPSAMPLE` times finer, each sample the raygun texel its
  direction falls in, and a sample lying exactly on a raygun row edge the mean of the two
  rows (`mitsuba_envmap_texels`): the same function except for a symmetric linear ramp
  within 1/ENV_UPSAMPLE texel of each texel edge. (Without the edge means every row edge
  moved 1/(2 ENV_UPSAMPLE) texel towards the zenith: +1 % in the directly seen sky, +4 % at
  the horizon in the envmap reference.)
* Integrator: `path`, max_depth = raygun's --max-depth + 1, rr_depth = 4 (raygun starts
  Russian roulette after the BSDF sample of its fourth vertex, depth index 3, with the same
  probability min(max(throughput), 0.95); Mitsuba increments depth before its test
  `depth >= rr_depth`).
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass, field

import numpy as np

try:  # imported as a package module or run from tools/peers/
    from . import exr, glb
except ImportError:  # pragma: no cover
    import exr  # type: ignore
    import glb  # type: ignore

MIN_ALPHA = 1e-3
EMITTER_GAP = 1e-5
ENV_UPSAMPLE = 8


# ---------------------------------------------------------------------------------------------
# The scene as raygun sees it


@dataclass
class Material:
    name: str
    base_color: np.ndarray  # linear RGBA factor
    texture: np.ndarray | None = None  # (H, W, 4) uint8 sRGB, row 0 = v 0
    metallic: float = 1.0
    roughness: float = 1.0
    specular: float = 1.0
    emission: np.ndarray = field(default_factory=lambda: np.zeros(3))
    double_sided: bool = False
    transmission: float = 0.0  # KHR_materials_transmission
    ior: float = 1.5  # KHR_materials_ior
    # KHR_materials_volume: sigma = -ln(attenuationColor) / attenuationDistance per unit length
    # (zero for a thin-walled material, thicknessFactor 0), as src/scene/load.rs computes it.
    absorption: np.ndarray = field(default_factory=lambda: np.zeros(3))


@dataclass
class Light:
    """KHR_lights_punctual: kind "point" or "spot" (cones in radians), colour x intensity."""
    name: str
    kind: str
    position: np.ndarray
    direction: np.ndarray
    intensity: np.ndarray
    inner: float = 0.0
    outer: float = math.pi / 4


@dataclass
class Camera:
    name: str
    position: np.ndarray
    forward: np.ndarray
    up: np.ndarray
    yfov: float


@dataclass
class Primitive:
    name: str
    material: int
    positions: np.ndarray  # (N, 3) world
    normals: np.ndarray | None  # (N, 3) world, unit
    uvs: np.ndarray | None  # (N, 2)
    faces: np.ndarray  # (M, 3) uint32, counter-clockwise = front


@dataclass
class Scene:
    path: str
    primitives: list[Primitive]
    materials: list[Material]
    cameras: list[Camera]
    lights: list[Light] = field(default_factory=list)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        ps = np.concatenate([p.positions for p in self.primitives])
        return ps.min(0), ps.max(0)

    def camera(self, name: str | None) -> Camera:
        if name is None:
            if not self.cameras:
                raise ValueError(f"{self.path}: no camera")
            return self.cameras[0]
        for c in self.cameras:
            if c.name == name:
                return c
        raise ValueError(f"{self.path}: no camera '{name}' ({[c.name for c in self.cameras]})")

    def triangle_count(self) -> int:
        return sum(len(p.faces) for p in self.primitives)


def _decode_image(data: bytes) -> np.ndarray:
    """PNG/JPEG bytes -> (H, W, 4) uint8, through Mitsuba's Bitmap (no other dependency)."""
    import mitsuba as mi

    with tempfile.NamedTemporaryFile(suffix=".img", delete=False) as f:
        f.write(data)
        name = f.name
    try:
        bmp = mi.Bitmap(name)
        bmp = bmp.convert(mi.Bitmap.PixelFormat.RGBA, mi.Struct.Type.UInt8, srgb_gamma=True)
        return np.array(bmp).reshape(bmp.height(), bmp.width(), 4).copy()
    finally:
        os.unlink(name)


def _material(g: glb.Gltf, index: int | None, textures: dict) -> Material:
    if index is None:
        return Material("default", np.ones(4), metallic=1.0, roughness=1.0)
    m = g.json["materials"][index]
    pbr = m.get("pbrMetallicRoughness", {})
    clamp = lambda v: float(min(max(v, 0.0), 1.0))  # noqa: E731
    ext = m.get("extensions", {})
    strength = ext.get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
    spec = 1.0
    if "KHR_materials_specular" in ext:
        f = ext["KHR_materials_specular"].get("specularFactor", 1.0)
        spec = clamp(f) if math.isfinite(f) else 1.0
    tex = None
    bct = pbr.get("baseColorTexture")
    if bct is not None and bct.get("texCoord", 0) == 0:
        ti = bct["index"]
        if ti not in textures:
            src = g.json["textures"][ti].get("source")
            textures[ti] = None if src is None else _decode_image(g.image_bytes(src))
        tex = textures[ti]
    return Material(
        name=m.get("name", f"material {index}"),
        base_color=np.array([clamp(v) for v in pbr.get("baseColorFactor", [1, 1, 1, 1])]),
        texture=tex,
        metallic=clamp(pbr.get("metallicFactor", 1.0)),
        roughness=clamp(pbr.get("roughnessFactor", 1.0)),
        specular=spec,
        emission=np.array([clamp(v) for v in m.get("emissiveFactor", [0, 0, 0])]) * strength,
        double_sided=bool(m.get("doubleSided", False)),
        transmission=clamp(ext.get("KHR_materials_transmission", {}).get("transmissionFactor", 0.0)),
        ior=float(ext.get("KHR_materials_ior", {}).get("ior", 1.5)),
        absorption=_absorption(ext.get("KHR_materials_volume")),
    )


def _absorption(volume: dict | None) -> np.ndarray:
    if not volume or volume.get("thicknessFactor", 0.0) <= 0.0:
        return np.zeros(3)
    dist = float(volume.get("attenuationDistance", math.inf))
    colour = np.clip(np.array(volume.get("attenuationColor", [1.0, 1.0, 1.0]), float), 0, 1)
    if not math.isfinite(dist):
        return np.zeros(3)
    with np.errstate(divide="ignore"):
        return np.minimum(-np.log(colour) / dist, 1e22)


def load(path: str) -> Scene:
    """Loads a glTF/GLB file as raygun does (see the module docstring)."""
    g = glb.Gltf.load(path)
    doc = g.json
    scenes = doc.get("scenes", [])
    roots = scenes[doc.get("scene", 0)]["nodes"] if scenes else []
    materials: list[Material] = []
    mat_index: dict = {}
    textures: dict = {}
    prims: list[Primitive] = []
    cameras: list[Camera] = []
    lights: list[Light] = []
    light_defs = doc.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
    stack = [(n, np.eye(4)) for n in reversed(roots)]
    while stack:
        ni, parent = stack.pop()
        node = doc["nodes"][ni]
        world = parent @ glb.node_matrix(node)
        if "camera" in node:
            cam = doc["cameras"][node["camera"]]
            if cam.get("type") == "perspective":
                pos = world[:3, 3].copy()
                fwd = world[:3, :3] @ np.array([0.0, 0.0, -1.0])
                fwd /= np.linalg.norm(fwd)
                up = world[:3, :3] @ np.array([0.0, 1.0, 0.0])
                up -= fwd * up.dot(fwd)
                up /= np.linalg.norm(up)
                name = node.get("name") or cam.get("name") or f"camera {ni}"
                cameras.append(Camera(name, pos, fwd, up, float(cam["perspective"]["yfov"])))
        li = node.get("extensions", {}).get("KHR_lights_punctual", {}).get("light")
        if li is not None:
            ld = light_defs[li]
            fwd = world[:3, :3] @ np.array([0.0, 0.0, -1.0])
            spot = ld.get("spot", {})
            lights.append(Light(
                name=ld.get("name", f"light {li}"), kind=ld["type"],
                position=world[:3, 3].copy(), direction=fwd / np.linalg.norm(fwd),
                intensity=np.array(ld.get("color", [1, 1, 1]), float) * ld.get("intensity", 1.0),
                inner=float(spot.get("innerConeAngle", 0.0)),
                outer=float(spot.get("outerConeAngle", math.pi / 4))))
        if "mesh" in node:
            mesh = doc["meshes"][node["mesh"]]
            lin = world[:3, :3]
            det = np.linalg.det(lin)
            nmat = np.linalg.inv(lin).T if det != 0 else None
            for pi, prim in enumerate(mesh["primitives"]):
                if prim.get("mode", 4) != 4:
                    continue
                attrs = prim["attributes"]
                p = g.accessor(attrs["POSITION"]).astype(np.float64)
                p = p @ lin.T + world[:3, 3]
                n = None
                if "NORMAL" in attrs and nmat is not None:
                    n = g.accessor(attrs["NORMAL"]).astype(np.float64) @ nmat.T
                    ln = np.linalg.norm(n, axis=1, keepdims=True)
                    n = np.where(ln > 0, n / np.where(ln > 0, ln, 1), 0)
                uv = g.accessor(attrs["TEXCOORD_0"]) if "TEXCOORD_0" in attrs else None
                if "indices" in prim:
                    idx = g.accessor(prim["indices"]).reshape(-1).astype(np.uint32)
                else:
                    idx = np.arange(len(p), dtype=np.uint32)
                faces = idx[: len(idx) // 3 * 3].reshape(-1, 3)
                if det < 0:
                    faces = faces[:, [0, 2, 1]]
                # Zero-area triangles are dropped (raygun does too).
                e1 = p[faces[:, 1]] - p[faces[:, 0]]
                e2 = p[faces[:, 2]] - p[faces[:, 0]]
                area = np.linalg.norm(np.cross(e1, e2), axis=1)
                faces = faces[area > 0]
                key = prim.get("material")
                if key not in mat_index:
                    mat_index[key] = len(materials)
                    materials.append(_material(g, key, textures))
                name = f"{mesh.get('name', 'mesh')}#{node['mesh']}.{pi}"
                prims.append(Primitive(name, mat_index[key], p, n, uv, faces))
        for c in reversed(node.get("children", [])):
            stack.append((c, world))
    return Scene(path, prims, materials, cameras, lights)


# ---------------------------------------------------------------------------------------------
# Material conversion


def schlick(cos: np.ndarray, f0: float) -> np.ndarray:
    return f0 + (1 - f0) * (1 - cos) ** 5


def fresnel_conductor(cos: np.ndarray, n: float, k: float) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a conductor with IOR n + ik (from vacuum)."""
    eta = n + 1j * k
    sin2 = 1 - cos**2
    cos_t = np.sqrt(1 - sin2 / eta**2)
    rs = (cos - eta * cos_t) / (cos + eta * cos_t)
    rp = (eta * cos - cos_t) / (eta * cos + cos_t)
    return 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)


_FIT_CACHE: dict[float, tuple[float, float]] = {}


def conductor_fit(f0: float) -> tuple[float, float]:
    """(eta, k) with F(normal incidence) = f0 whose Fresnel curve is closest to Schlick's
    (least squares, cosine weighted)."""
    f0 = float(min(max(f0, 0.0), 1.0))
    if f0 >= 0.9999:
        return 0.0, 1.0
    key = round(f0, 6)
    if key in _FIT_CACHE:
        return _FIT_CACHE[key]
    c = np.linspace(1e-4, 1, 2001)
    target = schlick(c, f0)
    sq = math.sqrt(max(f0, 1e-8))
    lo, hi = (1 - sq) / (1 + sq), (1 + sq) / (1 - sq)
    best = None
    for n in np.geomspace(max(lo, 1e-4) * 1.0001, hi * 0.9999, 600):
        k2 = (f0 * (n + 1) ** 2 - (n - 1) ** 2) / (1 - f0)
        if k2 < 0:
            continue
        d = fresnel_conductor(c, n, math.sqrt(k2)) - target
        e = np.trapezoid(d * d * c, c)
        if best is None or e < best[0]:
            best = (e, float(n), float(math.sqrt(k2)))
    _FIT_CACHE[key] = (best[1], best[2])
    return _FIT_CACHE[key]


def _rgb(v) -> dict:
    return {"type": "rgb", "value": [float(x) for x in v[:3]]}


def _texture_dict(mat: Material, scale: np.ndarray) -> dict:
    """The base colour texture in linear RGB times the factor, as a Mitsuba bitmap (the
    sRGB decode happens per texel before bilinear filtering, as in raygun)."""
    import mitsuba as mi

    t = mat.texture.astype(np.float32)[..., :3] / 255.0
    lin = np.where(t <= 0.04045, t / 12.92, ((t + 0.055) / 1.055) ** 2.4)
    lin = (lin * scale[None, None, :3]).astype(np.float32)
    return {
        "type": "bitmap",
        "bitmap": mi.Bitmap(lin),
        "raw": True,
        "filter_type": "bilinear",
        "wrap_mode": "repeat",
    }


def bsdf_dict(mat: Material, model: str = "native") -> dict:
    """The Mitsuba BSDF for a raygun material (see the module docstring), two-sided.
    model "gltf": raygun's own BSDF as the Python plugin of gltf_bsdf.py (vectorised
    variants only; `gltf_bsdf.register()` first)."""
    base = mat.base_color[:3]
    refl = _texture_dict(mat, base) if mat.texture is not None else _rgb(base)
    alpha = max(mat.roughness**2, MIN_ALPHA)
    if model == "gltf":
        return {"type": "twosided", "bsdf": {
            "type": "gltf", "base_color": refl, "metallic": float(mat.metallic),
            "alpha": float(alpha), "specular": float(mat.specular)}}
    diffuse = {"type": "diffuse", "reflectance": refl}
    if mat.transmission >= 1.0 and mat.metallic <= 0:
        # Glass (KHR_materials_transmission + ior): Mitsuba's dielectric interfaces, exact
        # Fresnel where raygun uses Schlick on the rarer side (equal at normal incidence and
        # under total internal reflection). Not two-sided: the interface knows its inside.
        if mat.roughness <= 0:
            return {"type": "dielectric", "int_ior": float(mat.ior), "ext_ior": 1.0}
        return {"type": "roughdielectric", "distribution": "ggx", "alpha": alpha,
                "int_ior": float(mat.ior), "ext_ior": 1.0}
    if mat.specular > 0:
        f0 = 0.04 * mat.specular
        ior = (1 + math.sqrt(f0)) / (1 - math.sqrt(f0))
        dielectric = {
            "type": "roughplastic",
            "distribution": "ggx",
            "alpha": alpha,
            "int_ior": ior,
            "ext_ior": 1.0,
            "nonlinear": False,
            "diffuse_reflectance": refl,
        }
    else:
        dielectric = diffuse
    if mat.texture is not None:
        metal = {
            "type": "roughconductor",
            "distribution": "ggx",
            "alpha": alpha,
            "eta": 0.0,
            "k": 1.0,
            "specular_reflectance": refl,
        }
    else:
        fits = [conductor_fit(float(c)) for c in base]
        metal = {
            "type": "roughconductor",
            "distribution": "ggx",
            "alpha": alpha,
            "eta": {"type": "rgb", "value": [f[0] for f in fits]},
            "k": {"type": "rgb", "value": [f[1] for f in fits]},
        }
    if mat.metallic <= 0:
        inner = dielectric
    elif mat.metallic >= 1:
        inner = metal
    else:
        inner = {"type": "blendbsdf", "weight": float(mat.metallic), "bsdf_0": dielectric,
                 "bsdf_1": metal}
    return {"type": "twosided", "bsdf": inner}


def material_model(mat: Material, model: str = "native") -> str:
    """A one-line statement of how exactly the material maps (for the reference JSON)."""
    if model == "gltf":
        return "gltf plugin (raygun's BSDF formulas, exact)"
    if mat.transmission >= 1.0 and mat.metallic <= 0:
        kind = "dielectric" if mat.roughness <= 0 else "roughdielectric ggx"
        medium = ""
        if np.any(mat.absorption > 0):
            sigma = ", ".join(f"{v:.4g}" for v in mat.absorption)
            medium = f", interior homogeneous medium sigma_t ({sigma}) albedo 0 (exact)"
        return f"{kind} ior {mat.ior} (exact Fresnel vs Schlick on the rarer side){medium}"
    if mat.metallic <= 0 and mat.specular <= 0:
        return "diffuse (exact)"
    if mat.metallic >= 1:
        if mat.texture is None and np.all(mat.base_color[:3] >= 0.9999):
            return "roughconductor F=1 (exact Fresnel; separable vs height-correlated Smith)"
        return "roughconductor fitted eta/k (Schlick approximated; separable Smith)"
    if mat.metallic <= 0:
        return "roughplastic (not equivalent: glTF Schlick-weighted layer vs plastic)"
    return "blendbsdf(roughplastic, roughconductor) (not equivalent)"


# ---------------------------------------------------------------------------------------------
# Environment


def environment_to_mitsuba(env) -> dict:
    """`env` is an RGB triple (constant radiance) or an (H, W, 3) raygun equirectangular map."""
    import mitsuba as mi

    if env is None:
        env = (1.0, 1.0, 1.0)
    arr = np.asarray(env, np.float32)
    if arr.ndim == 1:
        return {"type": "constant", "radiance": _rgb(arr)}
    return {"type": "envmap", "bitmap": mi.Bitmap(mitsuba_envmap_texels(arr)), "scale": 1.0}


def mitsuba_envmap_texels(tex: np.ndarray, up: int = ENV_UPSAMPLE) -> np.ndarray:
    """Resamples a raygun equirectangular map (nearest-texel function) onto Mitsuba's envmap
    grid: W' = up W columns at u_m = (j + 0.5) / W' (raygun's u = u_m + 0.5 mod 1), so raygun's
    column edges fall midway between two samples; H' = up H + 1 rows at v = i / (H' - 1), so
    raygun's row edges fall on a sample, which gets the mean of the two rows it separates.
    Mitsuba's bilinear interpolation then ramps symmetrically across every texel edge (over
    1/up of a texel) and the map's integral is raygun's."""
    h, w, _ = tex.shape
    wm, hm = up * w, up * h + 1
    um = (np.arange(wm) + 0.5) / wm
    u = np.mod(um + 0.5, 1.0)
    col = np.minimum((u * w).astype(np.int64), w - 1)
    cols = tex[:, col]  # (h, wm, 3)
    rows = np.empty((hm, wm, 3), np.float32)
    for i in range(hm):
        r, edge = divmod(i, up)
        if edge == 0 and 0 < r < h:
            rows[i] = 0.5 * (cols[r - 1] + cols[r])
        else:
            rows[i] = cols[min(r, h - 1)]
    return np.ascontiguousarray(rows, np.float32)


def equirect_direction(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """raygun's (u, v) -> unit direction (src/trace/shading.rs `equirect_to_direction`)."""
    phi = (u - 0.5) * 2 * np.pi
    theta = v * np.pi
    phi, theta = np.broadcast_arrays(phi, theta)
    s = np.sin(theta)
    return np.stack([s * np.sin(phi), np.cos(theta), -s * np.cos(phi)], axis=-1)


def load_environment(arg: str | None):
    """raygun's --env argument: None (white, radiance 1), 'R,G,B' or an .exr map."""
    if arg is None:
        return (1.0, 1.0, 1.0)
    parts = arg.split(",")
    try:
        vals = [float(p) for p in parts]
        if len(vals) == 3:
            return tuple(vals)
    except ValueError:
        pass
    if arg.lower().endswith(".exr"):
        return exr.read_rgb(arg)
    raise ValueError(f"--env '{arg}': expected R,G,B or an .exr file")


# ---------------------------------------------------------------------------------------------
# The Mitsuba scene


def _mesh(mi, name: str, prim: Primitive, props) -> object:
    """A Mitsuba mesh from world-space arrays (any variant)."""
    has_n = prim.normals is not None
    has_uv = prim.uvs is not None
    m = mi.Mesh(name, len(prim.positions), len(prim.faces), props,
                has_vertex_normals=has_n, has_vertex_texcoords=has_uv)
    params = mi.traverse(m)
    tf = type(params["vertex_positions"])
    tu = type(params["faces"])
    params["vertex_positions"] = tf(prim.positions.astype(np.float32).reshape(-1))
    params["faces"] = tu(prim.faces.astype(np.uint32).reshape(-1))
    if has_n:
        params["vertex_normals"] = tf(prim.normals.astype(np.float32).reshape(-1))
    if has_uv:
        params["vertex_texcoords"] = tf(prim.uvs.astype(np.float32).reshape(-1))
    params.update()
    return m


def _reversed_copy(prim: Primitive, gap: float) -> Primitive:
    """The primitive's triangles with reversed winding and normals, unshared, each moved by
    `gap` against its face normal."""
    f = prim.faces
    p = prim.positions[f]  # (M, 3, 3)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    p = p - gap * n[:, None, :]
    p = p[:, [0, 2, 1]]
    normals = None
    if prim.normals is not None:
        normals = -prim.normals[f][:, [0, 2, 1]].reshape(-1, 3)
    uvs = prim.uvs[f][:, [0, 2, 1]].reshape(-1, 2) if prim.uvs is not None else None
    faces = np.arange(3 * len(f), dtype=np.uint32).reshape(-1, 3)
    return Primitive(prim.name + " (back)", prim.material, p.reshape(-1, 3), normals, uvs, faces)


def mitsuba_dict(
    scene: Scene,
    width: int,
    height: int,
    spp: int,
    max_depth: int,
    camera: str | None = None,
    env=None,
    seed: int = 0,
    integrator: dict | None = None,
    model: str = "native",
) -> dict:
    """The Mitsuba 3 scene dict; `max_depth` in raygun's convention (path vertices).
    model: "native" (Mitsuba's BSDFs, the mapping above) or "gltf" (gltf_bsdf.py)."""
    import mitsuba as mi

    if model == "gltf":
        try:
            from . import gltf_bsdf
        except ImportError:  # pragma: no cover
            import gltf_bsdf  # type: ignore
        gltf_bsdf.register()

    cam = scene.camera(camera)
    lo, hi = scene.bounds()
    gap = EMITTER_GAP * float(np.linalg.norm(hi - lo))
    d: dict = {"type": "scene"}
    # An absorbing medium needs Mitsuba's volumetric path tracer (its `path` ignores media);
    # without scattering it is `path` with exp(-sigma t) over each segment inside.
    media = any(np.any(m.absorption > 0) for m in scene.materials)
    d["integrator"] = integrator or {
        "type": "volpath" if media else "path",
        "max_depth": int(max_depth) + 1,
        "rr_depth": 4,
        "hide_emitters": False,
    }
    d["sensor"] = {
        "type": "perspective",
        "fov": math.degrees(cam.yfov),
        "fov_axis": "y",
        "near_clip": 1e-3,
        "far_clip": 1e7,
        "to_world": mi.ScalarTransform4f().look_at(
            origin=[float(x) for x in cam.position],
            target=[float(x) for x in cam.position + cam.forward],
            up=[float(x) for x in cam.up],
        ),
        "film": {
            "type": "hdrfilm",
            "width": int(width),
            "height": int(height),
            "pixel_format": "rgb",
            "component_format": "float32",
            "rfilter": {"type": "box"},
        },
        "sampler": {"type": "independent", "sample_count": int(spp), "seed": int(seed)},
    }
    d["environment"] = environment_to_mitsuba(env)
    for i, prim in enumerate(scene.primitives):
        if len(prim.faces) == 0:
            continue
        mat = scene.materials[prim.material]
        emissive = bool(np.any(mat.emission > 0))
        copies = [prim]
        if emissive and mat.double_sided:
            copies.append(_reversed_copy(prim, gap))
        for j, pr in enumerate(copies):
            props = mi.Properties()
            props["bsdf"] = mi.load_dict(bsdf_dict(mat, model))
            if emissive:
                props["emitter"] = mi.load_dict({"type": "area", "radiance": _rgb(mat.emission)})
            if np.any(mat.absorption > 0):
                # The medium inside the closed mesh: absorbing only (albedo 0), so Mitsuba's
                # volpath attenuates by exp(-sigma t) over the length travelled inside.
                # (Its RGB coefficients must lie in [0, 1]: the largest is the scale.)
                top = float(mat.absorption.max())
                props["interior"] = mi.load_dict({
                    "type": "homogeneous", "sigma_t": _rgb(mat.absorption / top), "scale": top,
                    "albedo": {"type": "rgb", "value": [0.0, 0.0, 0.0]}})
            d[f"shape_{i}_{j}"] = _mesh(mi, f"{pr.name}", pr, props)
    for k, light in enumerate(scene.lights):
        if light.kind == "point":
            d[f"light_{k}"] = {"type": "point", "position": [float(x) for x in light.position],
                               "intensity": _rgb(light.intensity)}
        elif light.kind == "spot":
            # Mitsuba's falloff is linear in angle between beam_width and cutoff_angle, glTF's
            # quadratic in cos: the suite uses a 0.5 deg transition so that they agree.
            up = np.array([0.0, 1.0, 0.0]) if abs(light.direction[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
            d[f"light_{k}"] = {
                "type": "spot", "intensity": _rgb(light.intensity),
                "cutoff_angle": math.degrees(light.outer), "beam_width": math.degrees(light.inner),
                "to_world": mi.ScalarTransform4f().look_at(
                    origin=[float(x) for x in light.position],
                    target=[float(x) for x in light.position + light.direction],
                    up=[float(x) for x in up])}
    return d


# ---------------------------------------------------------------------------------------------
# Scene files for the suite


def rewrite_glb(src: str, dst: str, edit) -> None:
    """Copies a GLB with its JSON changed by `edit(doc)` (binary chunk untouched)."""
    g = glb.Gltf.load(src)
    doc = g.json
    edit(doc)
    w = glb.GlbWriter()
    w.bin = bytearray(g.buffers[0]) if g.buffers else bytearray()
    w.views = doc.get("bufferViews", [])
    w.accessors = doc.get("accessors", [])
    w.write(dst, {k: v for k, v in doc.items() if k not in ("buffers", "bufferViews",
                                                            "accessors")})


def make_lambert(doc: dict, light_double_sided: bool | None = None) -> None:
    """Every non-metal material becomes pure Lambert (KHR_materials_specular factor 0);
    emissive materials get doubleSided `light_double_sided` when given."""
    used = set(doc.get("extensionsUsed", []))
    used.add("KHR_materials_specular")
    doc["extensionsUsed"] = sorted(used)
    for m in doc.get("materials", []):
        ext = m.setdefault("extensions", {})
        ext["KHR_materials_specular"] = {"specularFactor": 0.0}
        if light_double_sided is not None and any(v > 0 for v in m.get("emissiveFactor", [])):
            m["doubleSided"] = bool(light_double_sided)


def _quat_look(forward: np.ndarray, up: np.ndarray) -> list[float]:
    """The rotation (x, y, z, w) taking -Z to `forward` and +Y to `up`."""
    f = forward / np.linalg.norm(forward)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    m = np.stack([r, u, -f], axis=1)  # columns: local x, y, z in world
    t = np.trace(m)
    if t > 0:
        s = math.sqrt(t + 1) * 2
        w, x, y, z = 0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (
            m[1, 0] - m[0, 1]) / s
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = math.sqrt(1 + m[i, i] - m[j, j] - m[k, k]) * 2
        q = [0.0, 0.0, 0.0]
        q[i] = 0.25 * s
        q[j] = (m[j, i] + m[i, j]) / s
        q[k] = (m[k, i] + m[i, k]) / s
        w = (m[k, j] - m[j, k]) / s
        x, y, z = q
    return [float(x), float(y), float(z), float(w)]


def uv_sphere(centre, radius, rings=20, segments=40):
    """A smooth UV sphere: positions, normals, faces (counter-clockwise from outside)."""
    th = np.linspace(0, np.pi, rings + 1)
    ph = np.linspace(0, 2 * np.pi, segments + 1)
    tt, pp = np.meshgrid(th, ph, indexing="ij")
    n = np.stack([np.sin(tt) * np.cos(pp), np.cos(tt), -np.sin(tt) * np.sin(pp)], -1)
    n = n.reshape(-1, 3)
    p = np.asarray(centre) + radius * n
    faces = []
    for i in range(rings):
        for j in range(segments):
            a = i * (segments + 1) + j
            b, c, e = a + segments + 1, a + 1, a + segments + 2
            if i > 0:
                faces.append([a, b, c])
            if i < rings - 1:
                faces.append([c, b, e])
    f = np.array(faces, np.uint32)
    # Orient counter-clockwise seen from outside.
    tri = p[f]
    out = np.einsum("ij,ij->i", np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
                    tri.mean(1) - np.asarray(centre))
    f[out < 0] = f[out < 0][:, [0, 2, 1]]
    return p.astype(np.float32), n.astype(np.float32), f


def write_objects_glb(path: str, objects: list[dict], materials: list[dict],
                      camera: dict, lights: list[dict] | None = None) -> None:
    """A GLB of `objects` ({name, positions, normals, faces, material}) in world space, glTF
    `materials` as given, one camera {name, position, target, yfov} and KHR_lights_punctual
    `lights` ({type, position, target, intensity[, inner, outer]})."""
    w = glb.GlbWriter()
    meshes, nodes = [], []
    for o in objects:
        prim = {
            "attributes": {"POSITION": w.add(o["positions"]), "NORMAL": w.add(o["normals"])},
            "indices": w.add(o["faces"], indices=True),
            "material": o["material"],
        }
        meshes.append({"name": o["name"], "primitives": [prim]})
        nodes.append({"name": o["name"], "mesh": len(meshes) - 1})
    pos = np.asarray(camera["position"], np.float64)
    fwd = np.asarray(camera["target"], np.float64) - pos
    nodes.append({
        "name": camera["name"],
        "camera": 0,
        "translation": [float(x) for x in pos],
        "rotation": _quat_look(fwd, np.array([0.0, 1.0, 0.0])),
    })
    used = sorted({e for m in materials for e in m.get("extensions", {})})
    light_defs = []
    for k, li in enumerate(lights or []):
        pos_l = np.asarray(li["position"], np.float64)
        fwd_l = np.asarray(li.get("target", pos_l - [0, 1, 0]), np.float64) - pos_l
        up_l = np.array([0.0, 1.0, 0.0]) if abs(fwd_l[1]) < 0.9 * np.linalg.norm(fwd_l) else np.array([1.0, 0.0, 0.0])
        ld = {"type": li["type"], "intensity": float(li["intensity"])}
        if li["type"] == "spot":
            ld["spot"] = {"innerConeAngle": float(li["inner"]), "outerConeAngle": float(li["outer"])}
        light_defs.append(ld)
        nodes.append({"name": f"light {k}", "translation": [float(x) for x in pos_l],
                      "rotation": _quat_look(fwd_l, up_l),
                      "extensions": {"KHR_lights_punctual": {"light": k}}})
    doc = {
        "asset": {"version": "2.0", "generator": "raygun tools/peers/scenes.py"},
        "scene": 0,
        "scenes": [{"nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "cameras": [{"type": "perspective", "name": camera["name"],
                     "perspective": {"yfov": float(camera["yfov"]), "znear": 0.01}}],
    }
    if light_defs:
        used = sorted(set(used) | {"KHR_lights_punctual"})
        doc["extensions"] = {"KHR_lights_punctual": {"lights": light_defs}}
    if used:
        doc["extensionsUsed"] = used
    w.write(path, doc)


def quad(corners) -> dict:
    """Four corners counter-clockwise seen from the front."""
    c = np.asarray(corners, np.float32)
    n = np.cross(c[1] - c[0], c[2] - c[0])
    n /= np.linalg.norm(n)
    return {"positions": c, "normals": np.tile(n, (4, 1)).astype(np.float32),
            "faces": np.array([[0, 1, 2], [0, 2, 3]], np.uint32)}


def lambert(name, rgb) -> dict:
    return {"name": name, "doubleSided": True,
            "pbrMetallicRoughness": {"baseColorFactor": [*rgb, 1.0], "metallicFactor": 0.0,
                                     "roughnessFactor": 1.0},
            "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}}


def metal(name, rgb, roughness) -> dict:
    return {"name": name, "doubleSided": True,
            "pbrMetallicRoughness": {"baseColorFactor": [*rgb, 1.0], "metallicFactor": 1.0,
                                     "roughnessFactor": float(roughness)}}


def plastic(name, rgb, roughness) -> dict:
    return {"name": name, "doubleSided": True,
            "pbrMetallicRoughness": {"baseColorFactor": [*rgb, 1.0], "metallicFactor": 0.0,
                                     "roughnessFactor": float(roughness)}}


def glossy_scene(path: str) -> None:
    """Two spheres (radius 0.35 m) on a grey Lambert floor: a white metal (F0 = 1, Fresnel
    exact in Mitsuba) and a copper-coloured metal (fitted conductor), roughness 0.3
    (alpha 0.09)."""
    floor = quad([[-3, 0, 3], [3, 0, 3], [3, 0, -3], [-3, 0, -3]])
    objs = [dict(name="floor", material=0, **floor)]
    for i, x in enumerate([-0.45, 0.45]):
        p, n, f = uv_sphere([x, 0.35, 0.0], 0.35)
        objs.append({"name": f"sphere {i}", "positions": p, "normals": n, "faces": f,
                     "material": i + 1})
    mats = [lambert("floor", [0.5, 0.5, 0.5]), metal("white metal", [1.0, 1.0, 1.0], 0.3),
            metal("copper", [0.955, 0.638, 0.538], 0.3)]
    write_objects_glb(path, objs, mats, {"name": "front", "position": [0.0, 0.7, 2.2],
                                         "target": [0.0, 0.3, 0.0], "yfov": 0.6})


def envmap_scene(path: str) -> None:
    """A Lambert sphere (0.8) and a white-metal sphere (roughness 0.2) on a small Lambert
    floor; the camera sees the sky above the horizon behind them."""
    floor = quad([[-1.2, 0, 1.2], [1.2, 0, 1.2], [1.2, 0, -1.2], [-1.2, 0, -1.2]])
    objs = [dict(name="floor", material=0, **floor)]
    for i, x in enumerate([-0.45, 0.45]):
        p, n, f = uv_sphere([x, 0.35, 0.0], 0.35)
        objs.append({"name": f"sphere {i}", "positions": p, "normals": n, "faces": f,
                     "material": i + 1})
    mats = [lambert("floor", [0.6, 0.6, 0.6]), lambert("diffuse", [0.8, 0.8, 0.8]),
            metal("mirror-ish", [1.0, 1.0, 1.0], 0.2)]
    write_objects_glb(path, objs, mats, {"name": "front", "position": [0.0, 0.55, 2.4],
                                         "target": [0.0, 0.45, 0.0], "yfov": 0.75})


def glass(name, roughness, ior=1.5, attenuation=None) -> dict:
    """Glass; `attenuation` = (attenuationColor, attenuationDistance) fills it with an
    absorbing medium (KHR_materials_volume, thicknessFactor 1)."""
    ext = {"KHR_materials_transmission": {"transmissionFactor": 1.0},
           "KHR_materials_ior": {"ior": float(ior)}}
    if attenuation is not None:
        colour, distance = attenuation
        ext["KHR_materials_volume"] = {"thicknessFactor": 1.0,
                                       "attenuationColor": [float(c) for c in colour],
                                       "attenuationDistance": float(distance)}
    return {"name": name, "doubleSided": True,
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0,
                                     "roughnessFactor": float(roughness)},
            "extensions": ext}


def glass_scene(path: str, coloured: bool = False) -> None:
    """A smooth (dielectric) and a rough (roughness 0.3, alpha 0.09) glass sphere, ior 1.5,
    radius 0.35 m, on a two-coloured Lambert floor under the white sky: the floor's halves
    are seen refracted through them. `coloured`: both filled with absorbing media
    (KHR_materials_volume) - amber (attenuationColor 0.9, 0.5, 0.1 at 0.5 m) in the smooth
    one, blue-green (0.2, 0.6, 0.8 at 0.7 m) in the rough one."""
    objs = [dict(name="floor red", material=0,
                 **quad([[-3, 0, 3], [0, 0, 3], [0, 0, -3], [-3, 0, -3]])),
            dict(name="floor blue", material=1,
                 **quad([[0, 0, 3], [3, 0, 3], [3, 0, -3], [0, 0, -3]]))]
    for i, x in enumerate([-0.45, 0.45]):
        p, n, f = uv_sphere([x, 0.35, 0.0], 0.35, rings=40, segments=80)
        objs.append({"name": f"sphere {i}", "positions": p, "normals": n, "faces": f,
                     "material": i + 2})
    mats = [lambert("red", [0.7, 0.2, 0.15]), lambert("blue", [0.15, 0.3, 0.7]),
            glass("smooth glass", 0.0, attenuation=((0.9, 0.5, 0.1), 0.5) if coloured else None),
            glass("rough glass", 0.3, attenuation=((0.2, 0.6, 0.8), 0.7) if coloured else None)]
    write_objects_glb(path, objs, mats, {"name": "front", "position": [0.0, 0.7, 2.2],
                                         "target": [0.0, 0.3, 0.0], "yfov": 0.6})


def lights_scene(path: str) -> None:
    """A Lambert sphere on a Lambert floor lit only by a point light (intensity 2) and a spot
    light (intensity 6, cones 25 / 25.5 deg: a hard edge, where glTF's and Mitsuba's falloff
    curves agree)."""
    floor = quad([[-3, 0, 3], [3, 0, 3], [3, 0, -3], [-3, 0, -3]])
    p, n, f = uv_sphere([0.2, 0.35, 0.0], 0.35)
    objs = [dict(name="floor", material=0, **floor),
            {"name": "sphere", "positions": p, "normals": n, "faces": f, "material": 1}]
    mats = [lambert("floor", [0.6, 0.6, 0.6]), lambert("sphere", [0.8, 0.5, 0.3])]
    lights = [{"type": "point", "position": [-0.8, 1.0, 0.6], "intensity": 2.0},
              {"type": "spot", "position": [0.6, 1.4, 0.4], "target": [0.3, 0.0, -0.2],
               "intensity": 6.0, "inner": math.radians(25.0), "outer": math.radians(25.5)}]
    write_objects_glb(path, objs, mats, {"name": "front", "position": [0.0, 0.9, 2.4],
                                         "target": [0.0, 0.3, 0.0], "yfov": 0.7}, lights)


def sky_map(w: int = 64, h: int = 32) -> np.ndarray:
    """A test sky in raygun's equirectangular convention: a horizon-to-zenith gradient whose
    colour depends on the quadrant (+X red-ish, -Z yellow-ish, -X green-ish, +Z blue-ish), a
    dark brown ground and a 2 x 2-texel sun (radiance 60) at 30-40 deg elevation towards
    (+X, -Z)."""
    u = (np.arange(w) + 0.5) / w
    v = (np.arange(h) + 0.5) / h
    d = equirect_direction(u[None, :], v[:, None])
    tex = np.zeros((h, w, 3), np.float32)
    quads = {
        "+x": np.array([1.0, 0.45, 0.35]),
        "-z": np.array([1.0, 0.9, 0.4]),
        "-x": np.array([0.4, 0.9, 0.45]),
        "+z": np.array([0.35, 0.5, 1.0]),
    }
    for r in range(h):
        for c in range(w):
            x, y, z = d[r, c]
            if y < 0:
                tex[r, c] = [0.12, 0.09, 0.06]
                continue
            if abs(x) >= abs(z):
                q = quads["+x"] if x > 0 else quads["-x"]
            else:
                q = quads["-z"] if z < 0 else quads["+z"]
            tex[r, c] = q * (0.3 + 0.9 * y)
    # The sun: texels (col, row) = 2 x 2 at azimuth between +X and -Z.
    sun_u = 0.5 + math.atan2(1.0, 1.0) / (2 * math.pi)  # direction (1, ., -1)
    c0 = int(sun_u * w)
    r0 = int(h * (90 - 40) / 180)
    tex[r0 : r0 + 2, c0 : c0 + 2] = [60.0, 55.0, 45.0]
    return tex
