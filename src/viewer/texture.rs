//! The picture fitted to the window's largest texture.

/// The picture as a texture the window's GPU can hold: itself where both sides fit
/// `max_side` (egui's `max_texture_side`), else averaged over f × f blocks, f the smallest
/// integer that fits (blocks at the right and bottom edges average the pixels they hold).
/// The screen shows the picture smaller than its pixels anyway at such sizes (HORNET's native
/// 13519 × 5457 on a desktop); clicks map through the picture's own size, not the texture's.
#[must_use]
pub fn fit_texture(
    rgba: &[u8],
    [w, h]: [u32; 2],
    max_side: u32,
) -> (std::borrow::Cow<'_, [u8]>, [u32; 2]) {
    let f = w.max(h).div_ceil(max_side.max(1)).max(1);
    if f == 1 {
        return (rgba.into(), [w, h]);
    }
    let (tw, th) = (w.div_ceil(f), h.div_ceil(f));
    let mut out = vec![0u8; 4 * tw as usize * th as usize];
    for ty in 0..th {
        for tx in 0..tw {
            let mut sum = [0u32; 4];
            let mut n = 0u32;
            for y in ty * f..((ty + 1) * f).min(h) {
                for x in tx * f..((tx + 1) * f).min(w) {
                    let i = 4 * (y as usize * w as usize + x as usize);
                    for (s, &c) in sum.iter_mut().zip(&rgba[i..i + 4]) {
                        *s += u32::from(c);
                    }
                    n += 1;
                }
            }
            let o = 4 * (ty as usize * tw as usize + tx as usize);
            for (k, s) in sum.iter().enumerate() {
                out[o + k] = ((s + n / 2) / n) as u8;
            }
        }
    }
    (out.into(), [tw, th])
}

#[cfg(test)]
mod texture_tests {
    use super::fit_texture;

    #[test]
    fn a_picture_too_large_for_a_texture_is_averaged_in_blocks_that_fit() {
        // 5 × 3, values 10·x + y in every channel.
        let rgba: Vec<u8> = (0..3u8)
            .flat_map(|y| (0..5u8).flat_map(move |x| [10 * x + y; 4]))
            .collect();
        let (same, size) = fit_texture(&rgba, [5, 3], 5);
        assert_eq!((&*same, size), (&rgba[..], [5, 3]));
        let (small, size) = fit_texture(&rgba, [5, 3], 2);
        assert_eq!(size, [2, 1], "f = 3: ⌈5/3⌉ × ⌈3/3⌉");
        // Block 0: x 0..3, y 0..3 → mean of 10x + y = 10 + 1; block 1: x 3..5 → 35 + 1.
        assert_eq!(&*small, [11, 11, 11, 11, 36, 36, 36, 36]);
        // HORNET's native canvas against an 8192 limit: 2 × 2 blocks, 6760 × 2729 texels.
        let big = vec![0u8; 4 * 13519 * 5457];
        assert_eq!(fit_texture(&big, [13519, 5457], 8192).1, [6760, 2729]);
    }
}
