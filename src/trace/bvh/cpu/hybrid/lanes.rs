//! The vector lanes a hybrid packet walks in ([`Lanes`]): sixteen rays in AVX-512 with mask
//! registers ([`Avx512`]), or in pairs of AVX2 registers ([`Avx2Pair`], over the eight lanes
//! of [`Avx2`], with masks held as all-ones lanes). The walks in `hybrid.rs` are written once
//! over the trait; each implementation is the same IEEE operation lane by lane (a `maxps` /
//! `minps` for [`Lanes::max`] / [`Lanes::min`], one rounding for [`Lanes::fmsub`]), so every
//! width finds the one-ray walks' hits to the bit.
//!
//! A value of a `Lanes` type is the proof that the processor has its instructions: [`Avx512`]
//! is made only by an `unsafe` promise, [`Avx2`] and [`Avx2Pair`] only in a build that targets
//! AVX2 and FMA.
//! The methods are `#[inline(always)]` so that they compile into the walks, which the caller
//! compiles for those instructions.

#[cfg(all(target_feature = "avx2", target_feature = "fma"))]
use std::arch::x86_64::{
    __m256, __m256i, _mm_cvtss_f32, _mm_min_ps, _mm_min_ss, _mm_movehl_ps, _mm_shuffle_ps,
    _mm256_add_epi32, _mm256_add_ps, _mm256_and_ps, _mm256_and_si256, _mm256_andnot_ps,
    _mm256_blendv_ps, _mm256_castps_si256, _mm256_castps256_ps128, _mm256_castsi256_ps,
    _mm256_cmp_ps, _mm256_cmpeq_epi32, _mm256_cmpgt_epi32, _mm256_div_ps, _mm256_extractf128_ps,
    _mm256_fmsub_ps, _mm256_loadu_ps, _mm256_loadu_si256, _mm256_max_ps, _mm256_min_ps,
    _mm256_movemask_ps, _mm256_mul_ps, _mm256_or_ps, _mm256_set1_epi32, _mm256_set1_ps,
    _mm256_setr_epi32, _mm256_storeu_ps, _mm256_storeu_si256, _mm256_sub_ps, _mm256_xor_ps,
    _mm256_xor_si256,
};
use std::arch::x86_64::{
    __m512, __m512i, __mmask16, _mm512_abs_ps, _mm512_add_epi32, _mm512_add_ps, _mm512_and_ps,
    _mm512_castps_si512, _mm512_castsi512_ps, _mm512_cmp_ps_mask, _mm512_cmpeq_epu32_mask,
    _mm512_cmpgt_epu32_mask, _mm512_div_ps, _mm512_fmsub_ps, _mm512_loadu_ps, _mm512_loadu_si512,
    _mm512_mask_blend_epi32, _mm512_mask_blend_ps, _mm512_mask_reduce_min_ps, _mm512_max_ps,
    _mm512_min_ps, _mm512_mul_ps, _mm512_or_ps, _mm512_set1_epi32, _mm512_set1_ps,
    _mm512_storeu_ps, _mm512_storeu_si512, _mm512_sub_ps, _mm512_xor_ps,
};

/// [`Lanes::WIDTH`] rays' values side by side: `F` floats, `I` 32-bit integers, `M` a mask of
/// lanes (what comparisons give and blends take); [`Lanes::bits`] turns a mask into an
/// integer, bit i for lane i, for the walks' decisions. Loads and stores use the first
/// `WIDTH` entries of sixteen.
pub(super) trait Lanes: Copy {
    const WIDTH: usize;
    type F: Copy;
    type I: Copy;
    type M: Copy;

    fn splat(self, x: f32) -> Self::F;
    fn splat_i(self, x: u32) -> Self::I;
    fn load(self, x: &[f32; 16]) -> Self::F;
    fn store(self, v: Self::F, out: &mut [f32; 16]);
    fn load_i(self, x: &[u32; 16]) -> Self::I;
    fn store_i(self, v: Self::I, out: &mut [u32; 16]);

    fn add(self, a: Self::F, b: Self::F) -> Self::F;
    fn sub(self, a: Self::F, b: Self::F) -> Self::F;
    fn mul(self, a: Self::F, b: Self::F) -> Self::F;
    fn div(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a · b − c`, rounded once.
    fn fmsub(self, a: Self::F, b: Self::F, c: Self::F) -> Self::F;
    /// `maxps`: `a` where `a > b`, else `b` (so `b` where either is NaN).
    fn max(self, a: Self::F, b: Self::F) -> Self::F;
    /// `minps`: `a` where `a < b`, else `b`.
    fn min(self, a: Self::F, b: Self::F) -> Self::F;
    /// The value with its sign bit cleared.
    fn abs(self, a: Self::F) -> Self::F;
    fn and(self, a: Self::F, b: Self::F) -> Self::F;
    fn or(self, a: Self::F, b: Self::F) -> Self::F;
    fn xor(self, a: Self::F, b: Self::F) -> Self::F;

    /// The lanes where `a` and `b` compare as predicate `P` says (`_CMP_*`: the same
    /// predicates for every lane type).
    fn cmp<const P: i32>(self, a: Self::F, b: Self::F) -> Self::M;
    fn eq_i(self, a: Self::I, b: Self::I) -> Self::M;
    /// `a > b` as unsigned integers.
    fn gt_u(self, a: Self::I, b: Self::I) -> Self::M;
    fn add_i(self, a: Self::I, b: Self::I) -> Self::I;
    /// The bits of `v` as integers, and back.
    fn as_i(self, v: Self::F) -> Self::I;
    fn as_f(self, v: Self::I) -> Self::F;

    fn and_m(self, a: Self::M, b: Self::M) -> Self::M;
    fn or_m(self, a: Self::M, b: Self::M) -> Self::M;
    /// The lanes of `b` not in `a`.
    fn andnot_m(self, a: Self::M, b: Self::M) -> Self::M;
    /// Bit i set where lane i is.
    fn bits(self, m: Self::M) -> u32;
    /// The lanes of the bits set in `bits` (below bit `WIDTH`).
    fn mask(self, bits: u32) -> Self::M;
    /// `b` in the lanes of `m`, `a` elsewhere.
    fn blend(self, m: Self::M, a: Self::F, b: Self::F) -> Self::F;
    fn blend_i(self, m: Self::M, a: Self::I, b: Self::I) -> Self::I;
    /// The least value among the lanes set in `bits` (at least one; none NaN).
    fn reduce_min(self, bits: u32, v: Self::F) -> f32;
}

/// Sixteen lanes of AVX-512 F and DQ.
#[derive(Clone, Copy)]
pub(super) struct Avx512(());

impl Avx512 {
    /// # Safety
    /// The processor must have AVX-512 F and DQ.
    #[inline(always)]
    pub(super) unsafe fn assume() -> Self {
        Self(())
    }
}

/// Runs one AVX-512 intrinsic. SAFETY (for every use below): an [`Avx512`] exists only where
/// the processor has AVX-512 F and DQ ([`Avx512::assume`]'s promise); the loads and stores
/// touch the sixteen entries of their arrays.
macro_rules! avx512 {
    ($e:expr) => {
        unsafe { $e }
    };
}

impl Lanes for Avx512 {
    const WIDTH: usize = 16;
    type F = __m512;
    type I = __m512i;
    type M = __mmask16;

    #[inline(always)]
    fn splat(self, x: f32) -> __m512 {
        avx512!(_mm512_set1_ps(x))
    }
    #[inline(always)]
    fn splat_i(self, x: u32) -> __m512i {
        avx512!(_mm512_set1_epi32(x as i32))
    }
    #[inline(always)]
    fn load(self, x: &[f32; 16]) -> __m512 {
        avx512!(_mm512_loadu_ps(x.as_ptr()))
    }
    #[inline(always)]
    fn store(self, v: __m512, out: &mut [f32; 16]) {
        avx512!(_mm512_storeu_ps(out.as_mut_ptr(), v))
    }
    #[inline(always)]
    fn load_i(self, x: &[u32; 16]) -> __m512i {
        avx512!(_mm512_loadu_si512(x.as_ptr().cast()))
    }
    #[inline(always)]
    fn store_i(self, v: __m512i, out: &mut [u32; 16]) {
        avx512!(_mm512_storeu_si512(out.as_mut_ptr().cast(), v))
    }
    #[inline(always)]
    fn add(self, a: __m512, b: __m512) -> __m512 {
        avx512!(_mm512_add_ps(a, b))
    }
    #[inline(always)]
    fn sub(self, a: __m512, b: __m512) -> __m512 {
        avx512!(_mm512_sub_ps(a, b))
    }
    #[inline(always)]
    fn mul(self, a: __m512, b: __m512) -> __m512 {
        avx512!(_mm512_mul_ps(a, b))
    }
    #[inline(always)]
    fn div(self, a: __m512, b: __m512) -> __m512 {
        avx512!(_mm512_div_ps(a, b))
    }
    #[inline(always)]
    fn fmsub(self, a: __m512, b: __m512, c: __m512) -> __m512 {
        avx512!(_mm512_fmsub_ps(a, b, c))
    }
    #[inline(always)]
    fn max(self, a: __m512, b: __m512) -> __m512 {
        avx512!(_mm512_max_ps(a, b))
    }
    #[inline(always)]
    fn min(self, a: __m512, b: __m512) -> __m512 {
        avx512!(_mm512_min_ps(a, b))
    }
    #[inline(always)]
    fn abs(self, a: __m512) -> __m512 {
        avx512!(_mm512_abs_ps(a))
    }
    #[inline(always)]
    fn and(self, a: __m512, b: __m512) -> __m512 {
        avx512!(_mm512_and_ps(a, b))
    }
    #[inline(always)]
    fn or(self, a: __m512, b: __m512) -> __m512 {
        avx512!(_mm512_or_ps(a, b))
    }
    #[inline(always)]
    fn xor(self, a: __m512, b: __m512) -> __m512 {
        avx512!(_mm512_xor_ps(a, b))
    }
    #[inline(always)]
    fn cmp<const P: i32>(self, a: __m512, b: __m512) -> __mmask16 {
        avx512!(_mm512_cmp_ps_mask::<P>(a, b))
    }
    #[inline(always)]
    fn eq_i(self, a: __m512i, b: __m512i) -> __mmask16 {
        avx512!(_mm512_cmpeq_epu32_mask(a, b))
    }
    #[inline(always)]
    fn gt_u(self, a: __m512i, b: __m512i) -> __mmask16 {
        avx512!(_mm512_cmpgt_epu32_mask(a, b))
    }
    #[inline(always)]
    fn add_i(self, a: __m512i, b: __m512i) -> __m512i {
        avx512!(_mm512_add_epi32(a, b))
    }
    #[inline(always)]
    fn as_i(self, v: __m512) -> __m512i {
        avx512!(_mm512_castps_si512(v))
    }
    #[inline(always)]
    fn as_f(self, v: __m512i) -> __m512 {
        avx512!(_mm512_castsi512_ps(v))
    }
    #[inline(always)]
    fn and_m(self, a: __mmask16, b: __mmask16) -> __mmask16 {
        a & b
    }
    #[inline(always)]
    fn or_m(self, a: __mmask16, b: __mmask16) -> __mmask16 {
        a | b
    }
    #[inline(always)]
    fn andnot_m(self, a: __mmask16, b: __mmask16) -> __mmask16 {
        !a & b
    }
    #[inline(always)]
    fn bits(self, m: __mmask16) -> u32 {
        u32::from(m)
    }
    #[inline(always)]
    fn mask(self, bits: u32) -> __mmask16 {
        bits as __mmask16
    }
    #[inline(always)]
    fn blend(self, m: __mmask16, a: __m512, b: __m512) -> __m512 {
        avx512!(_mm512_mask_blend_ps(m, a, b))
    }
    #[inline(always)]
    fn blend_i(self, m: __mmask16, a: __m512i, b: __m512i) -> __m512i {
        avx512!(_mm512_mask_blend_epi32(m, a, b))
    }
    #[inline(always)]
    fn reduce_min(self, bits: u32, v: __m512) -> f32 {
        avx512!(_mm512_mask_reduce_min_ps(bits as __mmask16, v))
    }
}

/// Eight lanes of AVX2 (with FMA): a mask is a vector whose lanes are all ones or all zeros.
#[cfg(all(target_feature = "avx2", target_feature = "fma"))]
#[derive(Clone, Copy)]
pub(super) struct Avx2(());

#[cfg(all(target_feature = "avx2", target_feature = "fma"))]
impl Avx2 {
    /// Eight lanes: the build targets AVX2 and FMA, so every processor it runs on has them.
    #[inline(always)]
    pub(super) fn new() -> Self {
        Self(())
    }
}

/// Runs AVX2 / FMA intrinsics. SAFETY (for every use below): this is compiled only where the
/// whole build targets AVX, AVX2 and FMA (the `cfg` on `Avx2`; `raygun` checks the processor at
/// start); the loads and stores touch the first eight entries of their arrays of sixteen.
#[cfg(all(target_feature = "avx2", target_feature = "fma"))]
macro_rules! avx2 {
    ($e:expr) => {
        unsafe { $e }
    };
}

#[cfg(all(target_feature = "avx2", target_feature = "fma"))]
impl Avx2 {
    /// The least of all eight lanes (none NaN).
    #[inline(always)]
    fn min_of(self, v: __m256) -> f32 {
        avx2!({
            let m = _mm_min_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps::<1>(v));
            let m = _mm_min_ps(m, _mm_movehl_ps(m, m));
            _mm_cvtss_f32(_mm_min_ss(m, _mm_shuffle_ps::<1>(m, m)))
        })
    }
}

#[cfg(all(target_feature = "avx2", target_feature = "fma"))]
impl Lanes for Avx2 {
    const WIDTH: usize = 8;
    type F = __m256;
    type I = __m256i;
    type M = __m256;

    #[inline(always)]
    fn splat(self, x: f32) -> __m256 {
        avx2!(_mm256_set1_ps(x))
    }
    #[inline(always)]
    fn splat_i(self, x: u32) -> __m256i {
        avx2!(_mm256_set1_epi32(x as i32))
    }
    #[inline(always)]
    fn load(self, x: &[f32; 16]) -> __m256 {
        avx2!(_mm256_loadu_ps(x.as_ptr()))
    }
    #[inline(always)]
    fn store(self, v: __m256, out: &mut [f32; 16]) {
        avx2!(_mm256_storeu_ps(out.as_mut_ptr(), v))
    }
    #[inline(always)]
    fn load_i(self, x: &[u32; 16]) -> __m256i {
        avx2!(_mm256_loadu_si256(x.as_ptr().cast()))
    }
    #[inline(always)]
    fn store_i(self, v: __m256i, out: &mut [u32; 16]) {
        avx2!(_mm256_storeu_si256(out.as_mut_ptr().cast(), v))
    }
    #[inline(always)]
    fn add(self, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_add_ps(a, b))
    }
    #[inline(always)]
    fn sub(self, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_sub_ps(a, b))
    }
    #[inline(always)]
    fn mul(self, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_mul_ps(a, b))
    }
    #[inline(always)]
    fn div(self, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_div_ps(a, b))
    }
    #[inline(always)]
    fn fmsub(self, a: __m256, b: __m256, c: __m256) -> __m256 {
        avx2!(_mm256_fmsub_ps(a, b, c))
    }
    #[inline(always)]
    fn max(self, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_max_ps(a, b))
    }
    #[inline(always)]
    fn min(self, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_min_ps(a, b))
    }
    #[inline(always)]
    fn abs(self, a: __m256) -> __m256 {
        avx2!(_mm256_andnot_ps(_mm256_set1_ps(-0.0), a))
    }
    #[inline(always)]
    fn and(self, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_and_ps(a, b))
    }
    #[inline(always)]
    fn or(self, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_or_ps(a, b))
    }
    #[inline(always)]
    fn xor(self, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_xor_ps(a, b))
    }
    #[inline(always)]
    fn cmp<const P: i32>(self, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_cmp_ps::<P>(a, b))
    }
    #[inline(always)]
    fn eq_i(self, a: __m256i, b: __m256i) -> __m256 {
        avx2!(_mm256_castsi256_ps(_mm256_cmpeq_epi32(a, b)))
    }
    #[inline(always)]
    fn gt_u(self, a: __m256i, b: __m256i) -> __m256 {
        // Unsigned order is signed order with the top bits flipped.
        avx2!({
            let top = _mm256_set1_epi32(i32::MIN);
            _mm256_castsi256_ps(_mm256_cmpgt_epi32(
                _mm256_xor_si256(a, top),
                _mm256_xor_si256(b, top),
            ))
        })
    }
    #[inline(always)]
    fn add_i(self, a: __m256i, b: __m256i) -> __m256i {
        avx2!(_mm256_add_epi32(a, b))
    }
    #[inline(always)]
    fn as_i(self, v: __m256) -> __m256i {
        avx2!(_mm256_castps_si256(v))
    }
    #[inline(always)]
    fn as_f(self, v: __m256i) -> __m256 {
        avx2!(_mm256_castsi256_ps(v))
    }
    #[inline(always)]
    fn and_m(self, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_and_ps(a, b))
    }
    #[inline(always)]
    fn or_m(self, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_or_ps(a, b))
    }
    #[inline(always)]
    fn andnot_m(self, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_andnot_ps(a, b))
    }
    #[inline(always)]
    fn bits(self, m: __m256) -> u32 {
        avx2!(_mm256_movemask_ps(m) as u32)
    }
    #[inline(always)]
    fn mask(self, bits: u32) -> __m256 {
        avx2!({
            let lanes = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
            let set = _mm256_and_si256(_mm256_set1_epi32(bits as i32), lanes);
            _mm256_castsi256_ps(_mm256_cmpeq_epi32(set, lanes))
        })
    }
    #[inline(always)]
    fn blend(self, m: __m256, a: __m256, b: __m256) -> __m256 {
        avx2!(_mm256_blendv_ps(a, b, m))
    }
    #[inline(always)]
    fn blend_i(self, m: __m256, a: __m256i, b: __m256i) -> __m256i {
        avx2!(_mm256_castps_si256(_mm256_blendv_ps(
            _mm256_castsi256_ps(a),
            _mm256_castsi256_ps(b),
            m
        )))
    }
    #[inline(always)]
    fn reduce_min(self, bits: u32, v: __m256) -> f32 {
        self.min_of(self.blend(self.mask(bits), self.splat(f32::INFINITY), v))
    }
}

/// Sixteen lanes as two AVX2 registers each: the sixteen-ray walks on a processor without
/// AVX-512 (every operation twice; masks as all-ones lanes). Measured against two packets of
/// eight: ×0.97 a whole render's time (BENCHMARKS.md, *CPU traversal*) — the packet's
/// decisions are made once for sixteen rays, though its rays no longer fit the sixteen
/// registers.
#[cfg(all(target_feature = "avx2", target_feature = "fma"))]
#[derive(Clone, Copy)]
pub(super) struct Avx2Pair(Avx2);

#[cfg(all(target_feature = "avx2", target_feature = "fma"))]
impl Avx2Pair {
    #[inline(always)]
    pub(super) fn new() -> Self {
        Self(Avx2::new())
    }
}

/// An [`Avx2`] operation on both halves.
#[cfg(all(target_feature = "avx2", target_feature = "fma"))]
macro_rules! both {
    ($l:expr, $op:ident, $($a:expr),+) => {
        [$l.$op($($a[0]),+), $l.$op($($a[1]),+)]
    };
}

#[cfg(all(target_feature = "avx2", target_feature = "fma"))]
impl Lanes for Avx2Pair {
    const WIDTH: usize = 16;
    type F = [__m256; 2];
    type I = [__m256i; 2];
    type M = [__m256; 2];

    #[inline(always)]
    fn splat(self, x: f32) -> Self::F {
        let v = self.0.splat(x);
        [v, v]
    }
    #[inline(always)]
    fn splat_i(self, x: u32) -> Self::I {
        let v = self.0.splat_i(x);
        [v, v]
    }
    #[inline(always)]
    fn load(self, x: &[f32; 16]) -> Self::F {
        let p = x.as_ptr();
        avx2!([_mm256_loadu_ps(p), _mm256_loadu_ps(p.add(8))])
    }
    #[inline(always)]
    fn store(self, v: Self::F, out: &mut [f32; 16]) {
        let p = out.as_mut_ptr();
        avx2!({
            _mm256_storeu_ps(p, v[0]);
            _mm256_storeu_ps(p.add(8), v[1]);
        })
    }
    #[inline(always)]
    fn load_i(self, x: &[u32; 16]) -> Self::I {
        let p = x.as_ptr();
        avx2!([
            _mm256_loadu_si256(p.cast()),
            _mm256_loadu_si256(p.add(8).cast())
        ])
    }
    #[inline(always)]
    fn store_i(self, v: Self::I, out: &mut [u32; 16]) {
        let p = out.as_mut_ptr();
        avx2!({
            _mm256_storeu_si256(p.cast(), v[0]);
            _mm256_storeu_si256(p.add(8).cast(), v[1]);
        })
    }
    #[inline(always)]
    fn add(self, a: Self::F, b: Self::F) -> Self::F {
        both!(self.0, add, a, b)
    }
    #[inline(always)]
    fn sub(self, a: Self::F, b: Self::F) -> Self::F {
        both!(self.0, sub, a, b)
    }
    #[inline(always)]
    fn mul(self, a: Self::F, b: Self::F) -> Self::F {
        both!(self.0, mul, a, b)
    }
    #[inline(always)]
    fn div(self, a: Self::F, b: Self::F) -> Self::F {
        both!(self.0, div, a, b)
    }
    #[inline(always)]
    fn fmsub(self, a: Self::F, b: Self::F, c: Self::F) -> Self::F {
        both!(self.0, fmsub, a, b, c)
    }
    #[inline(always)]
    fn max(self, a: Self::F, b: Self::F) -> Self::F {
        both!(self.0, max, a, b)
    }
    #[inline(always)]
    fn min(self, a: Self::F, b: Self::F) -> Self::F {
        both!(self.0, min, a, b)
    }
    #[inline(always)]
    fn abs(self, a: Self::F) -> Self::F {
        both!(self.0, abs, a)
    }
    #[inline(always)]
    fn and(self, a: Self::F, b: Self::F) -> Self::F {
        both!(self.0, and, a, b)
    }
    #[inline(always)]
    fn or(self, a: Self::F, b: Self::F) -> Self::F {
        both!(self.0, or, a, b)
    }
    #[inline(always)]
    fn xor(self, a: Self::F, b: Self::F) -> Self::F {
        both!(self.0, xor, a, b)
    }
    #[inline(always)]
    fn cmp<const P: i32>(self, a: Self::F, b: Self::F) -> Self::M {
        [self.0.cmp::<P>(a[0], b[0]), self.0.cmp::<P>(a[1], b[1])]
    }
    #[inline(always)]
    fn eq_i(self, a: Self::I, b: Self::I) -> Self::M {
        both!(self.0, eq_i, a, b)
    }
    #[inline(always)]
    fn gt_u(self, a: Self::I, b: Self::I) -> Self::M {
        both!(self.0, gt_u, a, b)
    }
    #[inline(always)]
    fn add_i(self, a: Self::I, b: Self::I) -> Self::I {
        both!(self.0, add_i, a, b)
    }
    #[inline(always)]
    fn as_i(self, v: Self::F) -> Self::I {
        both!(self.0, as_i, v)
    }
    #[inline(always)]
    fn as_f(self, v: Self::I) -> Self::F {
        both!(self.0, as_f, v)
    }
    #[inline(always)]
    fn and_m(self, a: Self::M, b: Self::M) -> Self::M {
        both!(self.0, and_m, a, b)
    }
    #[inline(always)]
    fn or_m(self, a: Self::M, b: Self::M) -> Self::M {
        both!(self.0, or_m, a, b)
    }
    #[inline(always)]
    fn andnot_m(self, a: Self::M, b: Self::M) -> Self::M {
        both!(self.0, andnot_m, a, b)
    }
    #[inline(always)]
    fn bits(self, m: Self::M) -> u32 {
        self.0.bits(m[0]) | self.0.bits(m[1]) << 8
    }
    #[inline(always)]
    fn mask(self, bits: u32) -> Self::M {
        [self.0.mask(bits & 0xff), self.0.mask(bits >> 8 & 0xff)]
    }
    #[inline(always)]
    fn blend(self, m: Self::M, a: Self::F, b: Self::F) -> Self::F {
        both!(self.0, blend, m, a, b)
    }
    #[inline(always)]
    fn blend_i(self, m: Self::M, a: Self::I, b: Self::I) -> Self::I {
        both!(self.0, blend_i, m, a, b)
    }
    #[inline(always)]
    fn reduce_min(self, bits: u32, v: Self::F) -> f32 {
        let inf = self.0.splat(f32::INFINITY);
        let m = self.mask(bits);
        let lo = self.0.blend(m[0], inf, v[0]);
        let hi = self.0.blend(m[1], inf, v[1]);
        self.0.min_of(self.0.min(lo, hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each operation of every lane type (eight AVX2 lanes, sixteen in AVX2 pairs, sixteen in
    /// AVX-512), lane by lane, against the scalar operation it stands for, on values that
    /// include ±0, ±∞, NaN, subnormals and the ends of the integers; masks through `bits` and
    /// `mask` both ways.
    #[test]
    fn lanes_are_the_scalar_operations() {
        let specials = [
            0.0f32,
            -0.0,
            1.0,
            -2.5,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MIN_POSITIVE / 4.0,
            3.0e38,
            -7.0e-3,
            0.1,
            1.0e-30,
            5.0,
            -5.0,
            2.0,
            0.5,
        ];
        let mut seed = 0x9e37_79b9u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        for round in 0..200 {
            let pick = |k: u32| -> f32 {
                if k.is_multiple_of(3) {
                    specials[(k as usize / 3) % 16]
                } else {
                    (k as f32 / u32::MAX as f32 - 0.5) * 20.0
                }
            };
            let a: [f32; 16] = std::array::from_fn(|_| pick(next()));
            let b: [f32; 16] = std::array::from_fn(|_| pick(next()));
            let c: [f32; 16] = std::array::from_fn(|_| pick(next()));
            let ia: [u32; 16] = std::array::from_fn(|i| if i == 3 { u32::MAX } else { next() });
            let ib: [u32; 16] = std::array::from_fn(|i| if i == 5 { 0 } else { next() });
            let bits = next() & 0xffff;
            let case = Case { a, b, c, ia, ib };
            #[cfg(all(target_feature = "avx2", target_feature = "fma"))]
            check(Avx2::new(), &case, bits & 0xff, round);
            #[cfg(all(target_feature = "avx2", target_feature = "fma"))]
            check(Avx2Pair::new(), &case, bits, round);
            if super::super::available() {
                // SAFETY: the processor has AVX-512 F and DQ (`available`).
                check(unsafe { Avx512::assume() }, &case, bits, round);
            }
        }
    }

    /// One round's operands: three float vectors and two integer vectors, sixteen lanes each.
    struct Case {
        a: [f32; 16],
        b: [f32; 16],
        c: [f32; 16],
        ia: [u32; 16],
        ib: [u32; 16],
    }

    fn check<L: Lanes>(l: L, case: &Case, bits: u32, round: u32) {
        let Case { a, b, c, ia, ib } = case;
        let w = L::WIDTH;
        let (va, vb, vc) = (l.load(a), l.load(b), l.load(c));
        let (via, vib) = (l.load_i(ia), l.load_i(ib));
        let out = |v: L::F| {
            let mut o = [0f32; 16];
            l.store(v, &mut o);
            o.map(f32::to_bits)
        };
        let out_i = |v: L::I| {
            let mut o = [0u32; 16];
            l.store_i(v, &mut o);
            o
        };
        let lanes = |f: &dyn Fn(usize) -> f32| -> [u32; 16] {
            std::array::from_fn(|i| if i < w { f(i).to_bits() } else { 0 })
        };
        let same = |what: &str, got: [u32; 16], want: [u32; 16]| {
            assert_eq!(got[..w], want[..w], "{what}, width {w}, round {round}");
        };
        let maxps = |x: f32, y: f32| if x > y { x } else { y };
        let minps = |x: f32, y: f32| if x < y { x } else { y };
        same("add", out(l.add(va, vb)), lanes(&|i| a[i] + b[i]));
        same("sub", out(l.sub(va, vb)), lanes(&|i| a[i] - b[i]));
        same("mul", out(l.mul(va, vb)), lanes(&|i| a[i] * b[i]));
        same("div", out(l.div(va, vb)), lanes(&|i| a[i] / b[i]));
        same(
            "fmsub",
            out(l.fmsub(va, vb, vc)),
            lanes(&|i| a[i].mul_add(b[i], -c[i])),
        );
        same("max", out(l.max(va, vb)), lanes(&|i| maxps(a[i], b[i])));
        same("min", out(l.min(va, vb)), lanes(&|i| minps(a[i], b[i])));
        same(
            "abs",
            out(l.abs(va)),
            lanes(&|i| f32::from_bits(a[i].to_bits() & !(1 << 31))),
        );
        let bit = |f: &dyn Fn(u32, u32) -> u32| -> [u32; 16] {
            std::array::from_fn(|i| {
                if i < w {
                    f(a[i].to_bits(), b[i].to_bits())
                } else {
                    0
                }
            })
        };
        same("and", out(l.and(va, vb)), bit(&|x, y| x & y));
        same("or", out(l.or(va, vb)), bit(&|x, y| x | y));
        same("xor", out(l.xor(va, vb)), bit(&|x, y| x ^ y));
        let mask_of =
            |f: &dyn Fn(usize) -> bool| (0..w).fold(0u32, |m, i| m | (u32::from(f(i)) << i));
        use std::arch::x86_64::{
            _CMP_EQ_OQ, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _CMP_NEQ_OQ,
        };
        assert_eq!(
            l.bits(l.cmp::<_CMP_LE_OQ>(va, vb)),
            mask_of(&|i| a[i] <= b[i])
        );
        assert_eq!(
            l.bits(l.cmp::<_CMP_LT_OQ>(va, vb)),
            mask_of(&|i| a[i] < b[i])
        );
        assert_eq!(
            l.bits(l.cmp::<_CMP_GE_OQ>(va, vb)),
            mask_of(&|i| a[i] >= b[i])
        );
        assert_eq!(
            l.bits(l.cmp::<_CMP_GT_OQ>(va, vb)),
            mask_of(&|i| a[i] > b[i])
        );
        assert_eq!(
            l.bits(l.cmp::<_CMP_EQ_OQ>(va, vb)),
            mask_of(&|i| a[i] == b[i])
        );
        // Ordered "not equal": false where either is NaN.
        assert_eq!(
            l.bits(l.cmp::<_CMP_NEQ_OQ>(va, vb)),
            mask_of(&|i| !a[i].is_nan() && !b[i].is_nan() && a[i] != b[i])
        );
        assert_eq!(l.bits(l.eq_i(via, vib)), mask_of(&|i| ia[i] == ib[i]));
        assert_eq!(l.bits(l.eq_i(via, via)), mask_of(&|_| true));
        assert_eq!(l.bits(l.gt_u(via, vib)), mask_of(&|i| ia[i] > ib[i]));
        let sum: [u32; 16] =
            std::array::from_fn(|i| if i < w { ia[i].wrapping_add(ib[i]) } else { 0 });
        assert_eq!(out_i(l.add_i(via, vib))[..w], sum[..w]);
        assert_eq!(out(l.as_f(l.as_i(va)))[..w], a.map(f32::to_bits)[..w]);
        let m = l.mask(bits);
        assert_eq!(l.bits(m), bits, "mask / bits, width {w}");
        let other = l.cmp::<_CMP_LT_OQ>(va, vb);
        let o = l.bits(other);
        assert_eq!(l.bits(l.and_m(m, other)), bits & o);
        assert_eq!(l.bits(l.or_m(m, other)), bits | o);
        assert_eq!(l.bits(l.andnot_m(m, other)), !bits & o);
        let pick = |i: usize| bits & (1 << i) != 0;
        same(
            "blend",
            out(l.blend(m, va, vb)),
            lanes(&|i| if pick(i) { b[i] } else { a[i] }),
        );
        let picked: [u32; 16] = std::array::from_fn(|i| if pick(i) { ib[i] } else { ia[i] });
        assert_eq!(out_i(l.blend_i(m, via, vib))[..w], picked[..w]);
        // The least of the set lanes (neither NaN nor zeros of two signs among them).
        let finite: [f32; 16] = std::array::from_fn(|i| {
            if a[i].is_nan() || a[i] == 0.0 {
                1.5
            } else {
                a[i]
            }
        });
        if bits != 0 {
            let want = (0..w)
                .filter(|&i| pick(i))
                .map(|i| finite[i])
                .fold(f32::INFINITY, f32::min);
            assert_eq!(
                l.reduce_min(bits, l.load(&finite)).to_bits(),
                want.to_bits()
            );
        }
    }
}
