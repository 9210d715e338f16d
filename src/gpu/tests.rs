use super::*;

#[test]
fn software_adapters_rank_after_real_gpus() {
    use wgpu::{Backend as B, DeviceType as D};
    assert!(adapter_rank(D::DiscreteGpu, B::Vulkan) < adapter_rank(D::DiscreteGpu, B::Gl));
    assert!(adapter_rank(D::DiscreteGpu, B::Gl) < adapter_rank(D::IntegratedGpu, B::Vulkan));
    assert!(adapter_rank(D::VirtualGpu, B::Vulkan) < adapter_rank(D::Cpu, B::Vulkan));
}

/// A kept value is made once a device, type and key: later calls, on the context and its
/// clones (another trace variant included, in a kernel-lab build), get it without making it
/// again; another key or type is made anew, and a new device keeps its own.
#[test]
fn kept_values_are_made_once_a_device_type_and_key() {
    let ctx = GpuContext::for_tests();
    let made = std::cell::Cell::new(0);
    let make = |v: u32| {
        made.set(made.get() + 1);
        v
    };
    assert_eq!(ctx.kept("a", || make(1)), 1);
    assert_eq!(ctx.kept("a", || make(2)), 1);
    let clone = ctx.clone();
    assert_eq!(clone.kept("a", || make(3)), 1);
    #[cfg(feature = "kernel-lab")]
    {
        let lab = ctx
            .with_trace_variant(variant::TraceVariant::default().with_workgroup(32))
            .unwrap();
        assert_eq!(lab.kept("a", || make(3)), 1);
    }
    assert_eq!(made.get(), 1);
    assert_eq!(ctx.kept("b", || make(4)), 4);
    assert_eq!(
        ctx.kept("a", || make(5) as u64),
        5,
        "another type, another value"
    );
    assert_eq!(made.get(), 3);
    let other = GpuContext::with_max_binding(1 << 20).unwrap();
    assert_eq!(
        other.kept("a", || make(6)),
        6,
        "another device keeps its own"
    );
}

/// Read-backs through kept staging buffers return exactly the source's bytes: a smaller
/// read through a larger kept buffer, the larger one again, a prefix, and two different
/// sources in turn; the kept bytes stay within the limit and clearing empties them.
#[test]
fn read_backs_through_kept_buffers_are_exact() {
    use wgpu::util::DeviceExt;
    let ctx = GpuContext::for_tests();
    let buffer = |words: u32, salt: u32| {
        let data: Vec<u32> = (0..words)
            .map(|i| i.wrapping_mul(2_654_435_761) ^ salt)
            .collect();
        let b = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("read-back test"),
                contents: bytemuck::cast_slice(&data),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            });
        (b, data)
    };
    let (big, big_data) = buffer(1 << 20, 7);
    let (small, small_data) = buffer(1000, 11);
    ctx.clear_staging();
    assert_eq!(ctx.read_buffer::<u32>(&big).unwrap(), big_data);
    assert_eq!(ctx.staging_kept_bytes(), 4 << 20, "the buffer is kept");
    // The small read goes through the kept 4 MiB buffer and returns its own bytes only.
    assert_eq!(ctx.read_buffer::<u32>(&small).unwrap(), small_data);
    assert_eq!(
        ctx.staging_kept_bytes(),
        4 << 20,
        "reused, not a second buffer"
    );
    assert_eq!(
        ctx.read_prefix::<u32>(&big, 400).unwrap(),
        big_data[..100].to_vec()
    );
    assert_eq!(ctx.read_buffer::<u32>(&big).unwrap(), big_data);
    // Two read-backs in a row of different buffers each see their own data.
    let (other, other_data) = buffer(1 << 20, 13);
    assert_eq!(ctx.read_buffer::<u32>(&other).unwrap(), other_data);
    assert_eq!(ctx.read_buffer::<u32>(&big).unwrap(), big_data);
    assert!(ctx.staging_kept_bytes() <= STAGING_KEEP_BYTES);
    ctx.clear_staging();
    assert_eq!(ctx.staging_kept_bytes(), 0);
}
