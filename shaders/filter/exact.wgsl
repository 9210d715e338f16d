// The paper's filter, exactly: one 2D window loop per pixel (a variable radius is not
// separable). Concatenated after common.wgsl. CPU twin: src/filter/exact.rs (f64).

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.size.x || gid.y >= params.size.y {
        return;
    }
    let i = gid.y * params.size.x + gid.x;
    let p = pixel_state(i);
    var o = p.mean;
    // w = 0 and k < 1 (the window is the pixel itself) pass u through bit for bit.
    if params.mode != MODE_OFF && p.w > 0.0 && p.k >= 1.0 {
        let f = window_mean(gid.x, gid.y, p.k);
        if f.w > 0.0 {
            o = p.w * f.xyz + (1.0 - p.w) * p.mean;
        }
    }
    out_image[i] = vec4<f32>(o, 1.0);
}
