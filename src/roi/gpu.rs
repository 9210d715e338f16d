//! Dispatch of `shaders/roi/dgi.wgsl`, the GPU twin of [`super::dgi::compute_cpu`].

use bytemuck::{Pod, Zeroable};
use glam::DVec2;
use wgpu::util::DeviceExt;

use super::conic::{ConicKind, Rect};
use super::dgi::{DgiParams, Guide, Surface};
use crate::gpu::{Band, GpuContext, GpuError, PassTimer};

/// The kernel source: the ellipse solver, then the DGI kernel (WGSL has no includes).
pub const DGI_WGSL: &str = concat!(
    include_str!("../../shaders/roi/ellipse.wgsl"),
    "\n",
    include_str!("../../shaders/roi/dgi.wgsl")
);

/// Mirrors `Params` in shaders/roi/dgi.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuParams {
    pub size: [u32; 2],
    pub mode: u32,
    pub count: u32,
    pub scale: [f32; 2],
    pub inv_falloff: f32,
    pub px_per_radian: f32,
    pub tan_hv: [f32; 2],
    /// L in canvas px (the distance cap), or f32::MAX for raw distances (WGSL need not honour
    /// infinities).
    pub cap: f32,
    pub _pad: u32,
}

/// Mirrors `Piece` in shaders/roi/dgi.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuPiece {
    pub center_i: [i32; 2],
    pub center_f: [f32; 2],
    pub half: [f32; 2],
    pub to_origin: [f32; 2],
    pub axis_u: [f32; 2],
    pub shape: [f32; 2],
    pub kind: u32,
    pub edge_start: u32,
    pub edge_count: u32,
    pub _pad: u32,
    /// The piece's bounding box relative to the rectangle centre (min.xy, max.xy).
    pub bounds: [f32; 4],
}

/// Mirrors `AngularTile` in shaders/roi/dgi.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuAngularTile {
    pub center_i: [i32; 2],
    pub center_f: [f32; 2],
    pub half: [f32; 2],
    pub _pad: [f32; 2],
    pub w0: [f32; 4],
    pub ex: [f32; 4],
    pub ey: [f32; 4],
}

/// A rectangle centre split into an integer image-pixel index and a fraction (f64 → i32 + f32),
/// so the kernel forms pixel offsets without losing f32 precision to the canvas's size.
fn split_center(canvas: &Rect, params: &DgiParams, rect: &Rect) -> ([i32; 2], [f32; 2]) {
    let r = (rect.center() - canvas.min) / params.scale(canvas) - 0.5;
    // Clamp keeps infinite (mouse/ellipse) rectangles representable; their centre is finite
    // anyway because they are clipped to the canvas.
    let ri = r.floor().clamp(DVec2::splat(-1e9), DVec2::splat(1e9));
    let rf = r - ri;
    ([ri.x as i32, ri.y as i32], [rf.x as f32, rf.y as f32])
}

fn f2(v: DVec2) -> [f32; 2] {
    [v.x as f32, v.y as f32]
}

/// The buffers' contents for one guide.
pub struct GpuGuide {
    pub params: GpuParams,
    pub pieces: Vec<GpuPiece>,
    pub edges: Vec<[f32; 4]>,
    pub tiles: Vec<GpuAngularTile>,
}

impl GpuGuide {
    #[must_use]
    pub fn new(surface: &Surface, guide: &Guide, params: &DgiParams) -> Self {
        let canvas = &surface.canvas;
        let scale = params.scale(canvas);
        let mut out = Self {
            params: GpuParams {
                size: [params.width, params.height],
                mode: 0,
                count: 0,
                scale: f2(scale),
                inv_falloff: params.falloff_px.map_or(0.0, |l| (1.0 / l) as f32),
                px_per_radian: 0.0,
                tan_hv: [1.0, 1.0],
                cap: params.falloff_px.map_or(f32::MAX, |l| l as f32),
                _pad: 0,
            },
            pieces: Vec::new(),
            edges: Vec::new(),
            tiles: Vec::new(),
        };
        match guide {
            Guide::Pieces(pieces) => {
                for p in pieces {
                    let (center_i, center_f) = split_center(canvas, params, &p.rect);
                    let rc = p.rect.center();
                    let (kind, shape) = match p.conic.kind {
                        ConicKind::Empty => (0, [0.0, 0.0]),
                        ConicKind::Ellipse { a, b } => (1, [a as f32, b as f32]),
                        ConicKind::Hyperbola { b2, s } => (2, [b2 as f32, s as f32]),
                        ConicKind::Parabola { c } => (3, [c as f32, 0.0]),
                    };
                    out.pieces.push(GpuPiece {
                        center_i,
                        center_f,
                        half: f2(0.5 * (p.rect.max - p.rect.min)),
                        to_origin: f2(p.conic.origin - rc),
                        axis_u: f2(p.conic.axis_u),
                        shape,
                        kind,
                        edge_start: out.edges.len() as u32,
                        edge_count: p.edges.len() as u32,
                        _pad: 0,
                        bounds: [
                            (p.bounds.min.x - rc.x) as f32,
                            (p.bounds.min.y - rc.y) as f32,
                            (p.bounds.max.x - rc.x) as f32,
                            (p.bounds.max.y - rc.y) as f32,
                        ],
                    });
                    for e in &p.edges {
                        let (a, b) = (e.a - rc, e.b - rc);
                        out.edges
                            .push([a.x as f32, a.y as f32, b.x as f32, b.y as f32]);
                    }
                }
                out.params.count = out.pieces.len() as u32;
            }
            Guide::Angular {
                cone,
                px_per_radian,
            } => {
                out.params.mode = 1;
                out.params.px_per_radian = *px_per_radian as f32;
                out.params.tan_hv = [cone.tan_h as f32, cone.tan_v as f32];
                let frame = |v: glam::DVec3| {
                    [
                        v.dot(cone.right) as f32,
                        v.dot(cone.up) as f32,
                        v.dot(cone.axis) as f32,
                        0.0,
                    ]
                };
                for patch in &surface.patches {
                    let (center_i, center_f) = split_center(canvas, params, &patch.rect);
                    let rc = patch.rect.center();
                    out.tiles.push(GpuAngularTile {
                        center_i,
                        center_f,
                        half: f2(0.5 * (patch.rect.max - patch.rect.min)),
                        _pad: [0.0; 2],
                        w0: frame(patch.point(rc) - cone.apex),
                        ex: frame(patch.ex),
                        ey: frame(patch.ey),
                    });
                }
                out.params.count = out.tiles.len() as u32;
            }
        }
        out
    }

    /// The same guide for the band of `rows` image rows from row `row0` (a frame split to fit
    /// the adapter's binding limit): the kernel's row `y` is image row `row0 + y`. Only the
    /// integer parts of the centres move, so every band pixel's offset from a centre, and
    /// its value, is the whole image's to the bit.
    #[must_use]
    pub fn band(mut self, row0: u32, rows: u32) -> Self {
        self.params.size[1] = rows;
        let shift = |c: &mut [i32; 2]| c[1] = c[1].saturating_sub_unsigned(row0);
        self.pieces.iter_mut().for_each(|p| shift(&mut p.center_i));
        self.tiles.iter_mut().for_each(|t| shift(&mut t.center_i));
        self
    }
}

/// The compiled DGI kernel.
pub struct DgiKernel {
    pipeline: wgpu::ComputePipeline,
}

/// Bytes per DGI value.
const VALUE_BYTES: u64 = 4;

impl DgiKernel {
    #[must_use]
    pub fn new(ctx: &GpuContext) -> Self {
        let pipeline = ctx.compute_pipeline("roi/dgi", DGI_WGSL, "main");
        Self { pipeline }
    }

    /// Computes the DGI on the GPU and reads it back (row-major, like the CPU twin).
    pub fn compute(
        &self,
        ctx: &GpuContext,
        surface: &Surface,
        guide: &Guide,
        params: &DgiParams,
    ) -> Result<Vec<f32>, GpuError> {
        let max = ctx.max_binding();
        // An image larger than one binding is computed in bands of rows (DESIGN.md §11).
        let bands = Band::split(params.width, params.height, VALUE_BYTES, max).ok_or(
            GpuError::TooLarge {
                what: "one row of the DGI output",
                bytes: u64::from(params.width) * VALUE_BYTES,
                max,
            },
        )?;
        let mut out = Vec::with_capacity(params.width as usize * params.height as usize);
        for band in bands {
            let run = self.prepare_band(ctx, surface, guide, params, band.row0, band.rows)?;
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            run.record(&mut enc, None);
            ctx.queue.submit([enc.finish()]);
            out.extend(ctx.read_buffer::<f32>(&run.output)?);
        }
        Ok(out)
    }

    /// Uploads the guide and allocates the output: everything but the dispatch.
    pub fn prepare(
        &self,
        ctx: &GpuContext,
        surface: &Surface,
        guide: &Guide,
        params: &DgiParams,
    ) -> Result<DgiRun, GpuError> {
        self.prepare_band(ctx, surface, guide, params, 0, params.height)
    }

    /// [`Self::prepare`] for the band of `rows` rows from image row `row0` alone: the output
    /// holds `width × rows` values, the band's rows of the whole image's DGI.
    pub fn prepare_band(
        &self,
        ctx: &GpuContext,
        surface: &Surface,
        guide: &Guide,
        params: &DgiParams,
        row0: u32,
        rows: u32,
    ) -> Result<DgiRun, GpuError> {
        debug_assert!(u64::from(row0) + u64::from(rows) <= u64::from(params.height));
        let g = GpuGuide::new(surface, guide, params).band(row0, rows);
        let bytes = u64::from(params.width) * u64::from(rows) * VALUE_BYTES;
        ctx.check_binding("DGI output", bytes)?;
        let storage = |label: &str, data: &[u8]| {
            ctx.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: data,
                    usage: wgpu::BufferUsages::STORAGE,
                })
        };
        // Bindings cannot be empty: pad each array with one unused element.
        let pieces = storage(
            "roi/dgi pieces",
            bytemuck::cast_slice(&nonempty(g.pieces, GpuPiece::zeroed())),
        );
        let edges = storage(
            "roi/dgi edges",
            bytemuck::cast_slice(&nonempty(g.edges, [0.0; 4])),
        );
        let tiles = storage(
            "roi/dgi tiles",
            bytemuck::cast_slice(&nonempty(g.tiles, GpuAngularTile::zeroed())),
        );
        let uniform = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("roi/dgi params"),
                contents: bytemuck::bytes_of(&g.params),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let output = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("roi/dgi output"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("roi/dgi"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                entry(0, &uniform),
                entry(1, &pieces),
                entry(2, &edges),
                entry(3, &tiles),
                entry(4, &output),
            ],
        });
        Ok(DgiRun {
            pipeline: self.pipeline.clone(),
            bind,
            output,
            groups: [params.width.div_ceil(16), rows.div_ceil(16)],
        })
    }
}

fn nonempty<T: Copy>(mut v: Vec<T>, filler: T) -> Vec<T> {
    if v.is_empty() {
        v.push(filler);
    }
    v
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// A prepared DGI dispatch: record it as often as needed (benchmarks repeat it).
pub struct DgiRun {
    pipeline: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    /// The DGI values, `width × height` f32, row-major.
    pub output: wgpu::Buffer,
    groups: [u32; 2],
}

impl DgiRun {
    /// Records the dispatch; with a timer, pass `pass` of it measures the kernel.
    pub fn record(&self, enc: &mut wgpu::CommandEncoder, timer: Option<(&PassTimer, u32)>) {
        self.record_with(enc, timer.map(|(t, i)| t.writes(i)));
    }

    /// Records the dispatch with these timestamp writes (a part of a split pass:
    /// [`PassTimer::writes_part`]).
    pub fn record_with(
        &self,
        enc: &mut wgpu::CommandEncoder,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("roi/dgi"),
            timestamp_writes,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind, &[]);
        pass.dispatch_workgroups(self.groups[0], self.groups[1], 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::wgsl::{assert_same_layout, validated};

    /// The kernel parses and validates without a GPU, and every struct shared with Rust has the
    /// same size on both sides (a mismatch would scramble the buffers silently).
    #[test]
    fn kernel_validates_and_shared_structs_match_their_rust_twins() {
        let module = validated("dgi.wgsl", DGI_WGSL);
        assert_same_layout(
            &module,
            "Params",
            &crate::rust_layout!(GpuParams; size, mode, count, scale, inv_falloff, px_per_radian,
                tan_hv, cap, _pad),
        );
        assert_same_layout(
            &module,
            "Piece",
            &crate::rust_layout!(GpuPiece; center_i, center_f, half, to_origin, axis_u, shape,
                kind, edge_start, edge_count, _pad, bounds),
        );
        assert_same_layout(
            &module,
            "AngularTile",
            &crate::rust_layout!(GpuAngularTile; center_i, center_f, half, _pad, w0, ex, ey),
        );
    }
}
