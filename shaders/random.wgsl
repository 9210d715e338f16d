// Counter-based random numbers shared by every kernel (CPU twin: src/random.rs).
//
// pcg4d from Jarzynski & Olano, "Hash Functions for GPU Rendering" (JCGT 2020): a bijective
// 4 × 32-bit → 4 × 32-bit hash with good avalanche. Every random number in raygun is a pure
// function of a counter (pixel, sample or iteration, seed, stream/dimension), so the CPU twin
// reproduces the kernel's decisions bit for bit and no state is stored between iterations.

fn pcg4d(v_in: vec4<u32>) -> vec4<u32> {
    var v = v_in * 1664525u + 1013904223u;
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    v = v ^ (v >> vec4<u32>(16u));
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    return v;
}

// The top 24 bits as a float in [0, 1): exact, and identical to the CPU's `unit_f32`.
fn unit_f32(x: u32) -> f32 {
    return f32(x >> 8u) * (1.0 / 16777216.0);
}
