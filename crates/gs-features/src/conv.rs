//! 3×3 convolution (pad 1, stride 1) + bias + ReLU and 2×2 max-pool on zero-padded HWC tensors.
//!
//! Two interchangeable convolution algorithms (see the workspace `BENCHMARKS.md` for the measurement):
//! * [`ConvAlgorithm::Im2colGemm`]: per band of image rows, gather the 3×3×C patches into a
//!   `[pixels][9·C]` matrix (im2col) and multiply by the `[9·C][Cout]` kernel matrix with
//!   `matrixmultiply::sgemm` (packed, cache-blocked, runtime AVX/FMA dispatch).
//! * [`ConvAlgorithm::Direct`]: a register-blocked direct convolution: 6 output pixels × 16
//!   output channels accumulate in 12 AVX registers while the kernel walks the 3 input rows
//!   (taps × input channels are contiguous in HWC), no patch matrix at all.
//!
//! Activations live in [`Padded`] tensors with a one-pixel zero border so that neither
//! algorithm needs bounds checks. Work is split over output rows with rayon; each output value
//! is computed by one thread in a fixed order, so results do not depend on the thread count.

use rayon::prelude::*;

/// Which convolution algorithm to run (both give the same result up to f32 rounding).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ConvAlgorithm {
    /// Direct register-blocked convolution.
    Direct,
    /// im2col + blocked sgemm (`matrixmultiply`): the default, 13–19 % faster than `Direct` on
    /// the idle 2-core machine at 800×600 (BENCHMARKS.md).
    #[default]
    Im2colGemm,
}

/// An HWC f32 tensor of `h × w × c` values stored with a one-pixel zero border:
/// `data[((y + 1) · (w + 2) + (x + 1)) · c + ch]` is the value at row `y`, column `x`.
#[derive(Debug, Clone, PartialEq)]
pub struct Padded {
    /// Interior height.
    pub h: usize,
    /// Interior width.
    pub w: usize,
    /// Channels.
    pub c: usize,
    /// `(h + 2) × (w + 2) × c` values, border zero.
    pub data: Vec<f32>,
}

impl Padded {
    /// A zero tensor.
    pub fn zeros(h: usize, w: usize, c: usize) -> Self {
        Self { h, w, c, data: vec![0.0; (h + 2) * (w + 2) * c] }
    }

    /// Floats per padded row.
    #[inline]
    pub fn row_len(&self) -> usize {
        (self.w + 2) * self.c
    }

    /// Value at interior `(y, x, ch)`.
    #[inline]
    pub fn get(&self, y: usize, x: usize, ch: usize) -> f32 {
        self.data[((y + 1) * (self.w + 2) + x + 1) * self.c + ch]
    }

    /// The interior as a dense row-major `[h][w][c]` vector.
    pub fn interior(&self) -> Vec<f32> {
        let mut out = Vec::with_capacity(self.h * self.w * self.c);
        for y in 0..self.h {
            let start = ((y + 1) * (self.w + 2) + 1) * self.c;
            out.extend_from_slice(&self.data[start..start + self.w * self.c]);
        }
        out
    }
}

/// A 3×3 conv layer prepared for both algorithms.
#[derive(Debug, Clone)]
pub struct PreparedConv {
    /// Output channels (a multiple of 16).
    pub cout: usize,
    /// Input channels.
    pub cin: usize,
    /// `[9·cin][cout]`, row `(ky·3 + kx)·cin + ci` (the im2col / GEMM operand).
    gemm_kernel: Vec<f32>,
    /// `[cout/16][3][3·cin][16]`: per block of 16 output channels, rows ky, then (kx, ci).
    direct_kernel: Vec<f32>,
    /// `[cout]`.
    bias: Vec<f32>,
}

/// Output channels per direct-kernel block (two 8-lane vectors).
const CO_BLOCK: usize = 16;
/// Output pixels per direct-kernel call.
const PX_BLOCK: usize = 6;

impl PreparedConv {
    /// Re-lays an OIHW `[cout][cin][3][3]` kernel for both algorithms.
    pub fn new(cout: usize, cin: usize, oihw: &[f32], bias: &[f32]) -> Self {
        assert_eq!(oihw.len(), cout * cin * 9);
        assert_eq!(bias.len(), cout);
        assert_eq!(cout % CO_BLOCK, 0, "cout must be a multiple of {CO_BLOCK}");
        let k = 9 * cin;
        let mut gemm_kernel = vec![0.0; k * cout];
        let mut direct_kernel = vec![0.0; k * cout];
        for co in 0..cout {
            for ci in 0..cin {
                for ky in 0..3 {
                    for kx in 0..3 {
                        let v = oihw[((co * cin + ci) * 3 + ky) * 3 + kx];
                        let row = (ky * 3 + kx) * cin + ci;
                        gemm_kernel[row * cout + co] = v;
                        let (cb, j) = (co / CO_BLOCK, co % CO_BLOCK);
                        direct_kernel[(cb * k + row) * CO_BLOCK + j] = v;
                    }
                }
            }
        }
        Self { cout, cin, gemm_kernel, direct_kernel, bias: bias.to_vec() }
    }

    /// The kernel as `[9·cin][cout]`, row `(ky·3 + kx)·cin + ci` (the device kernel's layout).
    #[cfg(feature = "wgpu")]
    pub(crate) fn gemm_kernel(&self) -> &[f32] {
        &self.gemm_kernel
    }

    /// The bias, `[cout]`.
    #[cfg(feature = "wgpu")]
    pub(crate) fn bias(&self) -> &[f32] {
        &self.bias
    }

    /// Multiply-accumulates of this layer on an `h × w` image.
    pub fn macs(&self, h: usize, w: usize) -> u64 {
        (h * w) as u64 * (9 * self.cin * self.cout) as u64
    }

    /// conv 3×3 (pad 1) + bias + ReLU over a whole tensor, parallel over output rows.
    pub fn forward(&self, input: &Padded, algorithm: ConvAlgorithm) -> Padded {
        assert_eq!(input.c, self.cin);
        let (h, w) = (input.h, input.w);
        let mut out = Padded::zeros(h, w, self.cout);
        let out_row_len = out.row_len();
        let in_row_len = input.row_len();
        let interior = &mut out.data[out_row_len..(h + 1) * out_row_len];
        interior.par_chunks_mut(out_row_len).enumerate().for_each_init(Vec::new, |col, (y, row)| {
            self.row(&input.data[y * in_row_len..(y + 3) * in_row_len], w, row, algorithm, col);
        });
        out
    }

    /// One padded output row (`(w + 2)·cout` values, border pixels set to zero) from the three
    /// padded input rows around it (`3·(w + 2)·cin` values). `col` is im2col scratch.
    pub fn row(&self, inp: &[f32], w: usize, out: &mut [f32], algorithm: ConvAlgorithm, col: &mut Vec<f32>) {
        let (cin, cout) = (self.cin, self.cout);
        let in_row_len = (w + 2) * cin;
        assert_eq!(inp.len(), 3 * in_row_len);
        assert_eq!(out.len(), (w + 2) * cout);
        out[..cout].fill(0.0);
        out[(w + 1) * cout..].fill(0.0);
        match algorithm {
            ConvAlgorithm::Im2colGemm => {
                let k = 9 * cin;
                col.resize(w * k, 0.0);
                for x in 0..w {
                    let dst = &mut col[x * k..(x + 1) * k];
                    for ky in 0..3 {
                        let src = ky * in_row_len + x * cin;
                        dst[ky * 3 * cin..(ky + 1) * 3 * cin].copy_from_slice(&inp[src..src + 3 * cin]);
                    }
                }
                let dst = &mut out[cout..(w + 1) * cout];
                // SAFETY: col is w×k, gemm_kernel is k×cout, dst is w×cout, all row-major with
                // the strides given; the slices do not overlap.
                unsafe {
                    matrixmultiply::sgemm(
                        w,
                        k,
                        cout,
                        1.0,
                        col.as_ptr(),
                        k as isize,
                        1,
                        self.gemm_kernel.as_ptr(),
                        cout as isize,
                        1,
                        0.0,
                        dst.as_mut_ptr(),
                        cout as isize,
                        1,
                    );
                }
                for px in dst.chunks_exact_mut(cout) {
                    for (v, b) in px.iter_mut().zip(&self.bias) {
                        *v = (*v + b).max(0.0);
                    }
                }
            }
            ConvAlgorithm::Direct => {
                let kb = 9 * cin * CO_BLOCK;
                let use_avx = avx2_fma_available();
                for cb in 0..cout / CO_BLOCK {
                    let wk = &self.direct_kernel[cb * kb..(cb + 1) * kb];
                    let bias = &self.bias[cb * CO_BLOCK..(cb + 1) * CO_BLOCK];
                    let mut x = 0;
                    while x < w {
                        let n = PX_BLOCK.min(w - x);
                        // Output pixel x sits at padded column x + 1; its window starts at x.
                        let out_off = (x + 1) * cout + cb * CO_BLOCK;
                        direct_block(use_avx, n, inp, in_row_len, x * cin, cin, wk, bias, out, out_off, cout);
                        x += n;
                    }
                }
            }
        }
    }
}

/// Output rows per strip of [`fused_block`].
const STRIP_ROWS: usize = 8;

/// Two convs (+ optional 2×2 max-pool) computed strip by strip: each strip of output rows
/// recomputes the one-row halo of the first conv in a small per-thread buffer, so the
/// full-resolution intermediate activations (123 MB each at 800×600 for block 1) are never
/// materialised. Same values as `b.forward(a.forward(x))` (+ [`max_pool2`]).
pub fn fused_block(
    input: &Padded,
    a: &PreparedConv,
    b: &PreparedConv,
    pool: bool,
    algorithm: ConvAlgorithm,
) -> Padded {
    assert_eq!(input.c, a.cin);
    assert_eq!(a.cout, b.cin);
    let (h, w) = (input.h, input.w);
    let (oh, ow) = if pool { (h / 2, w / 2) } else { (h, w) };
    let mut out = Padded::zeros(oh, ow, b.cout);
    let out_row_len = out.row_len();
    let in_row_len = input.row_len();
    let a_row_len = (w + 2) * a.cout;
    let b_row_len = (w + 2) * b.cout;
    let interior = &mut out.data[out_row_len..(oh + 1) * out_row_len];
    interior.par_chunks_mut(STRIP_ROWS * out_row_len).enumerate().for_each_init(
        || (Vec::new(), Vec::new(), Vec::new()),
        |(buf_a, buf_b, col), (strip, chunk)| {
            let o0 = strip * STRIP_ROWS;
            let n_out = chunk.len() / out_row_len;
            let (b0, b1) = if pool { (2 * o0, 2 * (o0 + n_out)) } else { (o0, o0 + n_out) };
            // buf_a row r holds conv-a row b0 - 1 + r (zero outside the image).
            let n_a = b1 - b0 + 2;
            buf_a.resize(n_a * a_row_len, 0.0);
            for r in 0..n_a {
                let dst = &mut buf_a[r * a_row_len..(r + 1) * a_row_len];
                let ya = (b0 + r) as isize - 1;
                if ya < 0 || ya as usize >= h {
                    dst.fill(0.0);
                } else {
                    let ya = ya as usize;
                    a.row(&input.data[ya * in_row_len..(ya + 3) * in_row_len], w, dst, algorithm, col);
                }
            }
            if pool {
                buf_b.resize(2 * b_row_len, 0.0);
                for o in 0..n_out {
                    for t in 0..2 {
                        let r = 2 * o + t; // conv-b row b0 + r needs buf_a rows r..r+3
                        b.row(
                            &buf_a[r * a_row_len..(r + 3) * a_row_len],
                            w,
                            &mut buf_b[t * b_row_len..(t + 1) * b_row_len],
                            algorithm,
                            col,
                        );
                    }
                    let (r0, r1) = buf_b.split_at(b_row_len);
                    pool_row(r0, r1, ow, b.cout, &mut chunk[o * out_row_len..(o + 1) * out_row_len]);
                }
            } else {
                for r in 0..n_out {
                    b.row(
                        &buf_a[r * a_row_len..(r + 3) * a_row_len],
                        w,
                        &mut chunk[r * out_row_len..(r + 1) * out_row_len],
                        algorithm,
                        col,
                    );
                }
            }
        },
    );
    out
}

/// One pooled padded row from two padded input rows (`ow` output pixels of `c` channels).
fn pool_row(r0: &[f32], r1: &[f32], ow: usize, c: usize, out: &mut [f32]) {
    for x in 0..ow {
        let o = &mut out[(x + 1) * c..(x + 2) * c];
        let a = (2 * x + 1) * c;
        let b = (2 * x + 2) * c;
        for ch in 0..c {
            o[ch] = r0[a + ch].max(r0[b + ch]).max(r1[a + ch]).max(r1[b + ch]);
        }
    }
}

/// Whether the AVX2 + FMA direct kernel can run on this CPU (checked once).
fn avx2_fma_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        static AVAILABLE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *AVAILABLE.get_or_init(|| {
            std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// One block of `n ≤ 6` output pixels × 16 output channels.
#[allow(clippy::too_many_arguments)]
#[inline]
fn direct_block(
    use_avx: bool,
    n: usize,
    inp: &[f32],
    in_row_len: usize,
    in_off: usize,
    cin: usize,
    wk: &[f32],
    bias: &[f32],
    out: &mut [f32],
    out_off: usize,
    cout: usize,
) {
    // Bounds the unchecked kernels rely on.
    assert!(in_off + (n + 2) * cin + 2 * in_row_len <= inp.len());
    assert!(wk.len() == 9 * cin * CO_BLOCK && bias.len() == CO_BLOCK);
    assert!(out_off + (n - 1) * cout + CO_BLOCK <= out.len());
    #[cfg(target_arch = "x86_64")]
    if use_avx {
        // SAFETY: AVX2 and FMA were detected at run time; the asserts above bound every access.
        unsafe {
            match n {
                6 => avx::block::<6>(inp, in_row_len, in_off, cin, wk, bias, out, out_off, cout),
                5 => avx::block::<5>(inp, in_row_len, in_off, cin, wk, bias, out, out_off, cout),
                4 => avx::block::<4>(inp, in_row_len, in_off, cin, wk, bias, out, out_off, cout),
                3 => avx::block::<3>(inp, in_row_len, in_off, cin, wk, bias, out, out_off, cout),
                2 => avx::block::<2>(inp, in_row_len, in_off, cin, wk, bias, out, out_off, cout),
                _ => avx::block::<1>(inp, in_row_len, in_off, cin, wk, bias, out, out_off, cout),
            }
        }
        return;
    }
    let _ = use_avx;
    portable_block(n, inp, in_row_len, in_off, cin, wk, bias, out, out_off, cout);
}

/// Portable version of the direct kernel (any CPU; auto-vectorised by LLVM).
#[allow(clippy::too_many_arguments)]
fn portable_block(
    n: usize,
    inp: &[f32],
    in_row_len: usize,
    in_off: usize,
    cin: usize,
    wk: &[f32],
    bias: &[f32],
    out: &mut [f32],
    out_off: usize,
    cout: usize,
) {
    let mut acc = [[0f32; CO_BLOCK]; PX_BLOCK];
    let kr = 3 * cin;
    for ky in 0..3 {
        let base = in_off + ky * in_row_len;
        let wrow = &wk[ky * kr * CO_BLOCK..(ky + 1) * kr * CO_BLOCK];
        for k in 0..kr {
            let wv: &[f32; CO_BLOCK] = wrow[k * CO_BLOCK..(k + 1) * CO_BLOCK].try_into().unwrap();
            for (p, a) in acc.iter_mut().enumerate().take(n) {
                let x = inp[base + p * cin + k];
                for j in 0..CO_BLOCK {
                    a[j] += x * wv[j];
                }
            }
        }
    }
    for (p, a) in acc.iter().enumerate().take(n) {
        let o = &mut out[out_off + p * cout..out_off + p * cout + CO_BLOCK];
        for j in 0..CO_BLOCK {
            o[j] = (a[j] + bias[j]).max(0.0);
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx {
    use super::CO_BLOCK;
    use std::arch::x86_64::*;

    /// `N` output pixels × 16 output channels: 2·N accumulators, one broadcast per input value,
    /// two kernel loads per (tap, input channel).
    ///
    /// # Safety
    /// AVX2 and FMA must be available; the caller bounds every index (see `direct_block`).
    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn block<const N: usize>(
        inp: &[f32],
        in_row_len: usize,
        in_off: usize,
        cin: usize,
        wk: &[f32],
        bias: &[f32],
        out: &mut [f32],
        out_off: usize,
        cout: usize,
    ) {
        // SAFETY: see the function's contract.
        unsafe {
            let mut acc = [[_mm256_setzero_ps(); 2]; N];
            let kr = 3 * cin;
            let ip = inp.as_ptr();
            let wp = wk.as_ptr();
            for ky in 0..3 {
                let base = ip.add(in_off + ky * in_row_len);
                let wrow = wp.add(ky * kr * CO_BLOCK);
                for k in 0..kr {
                    let w0 = _mm256_loadu_ps(wrow.add(k * CO_BLOCK));
                    let w1 = _mm256_loadu_ps(wrow.add(k * CO_BLOCK + 8));
                    for (p, a) in acc.iter_mut().enumerate() {
                        let x = _mm256_broadcast_ss(&*base.add(p * cin + k));
                        a[0] = _mm256_fmadd_ps(x, w0, a[0]);
                        a[1] = _mm256_fmadd_ps(x, w1, a[1]);
                    }
                }
            }
            let b0 = _mm256_loadu_ps(bias.as_ptr());
            let b1 = _mm256_loadu_ps(bias.as_ptr().add(8));
            let zero = _mm256_setzero_ps();
            let op = out.as_mut_ptr();
            for (p, a) in acc.iter().enumerate() {
                let o = op.add(out_off + p * cout);
                _mm256_storeu_ps(o, _mm256_max_ps(_mm256_add_ps(a[0], b0), zero));
                _mm256_storeu_ps(o.add(8), _mm256_max_ps(_mm256_add_ps(a[1], b1), zero));
            }
        }
    }
}

/// 2×2 max-pool, stride 2, floor rounding (odd last rows/columns dropped, as torch).
pub fn max_pool2(input: &Padded) -> Padded {
    let (h, w, c) = (input.h / 2, input.w / 2, input.c);
    let mut out = Padded::zeros(h, w, c);
    let out_row_len = out.row_len();
    let in_row_len = input.row_len();
    let interior = &mut out.data[out_row_len..(h + 1) * out_row_len];
    interior.par_chunks_mut(out_row_len).enumerate().for_each(|(y, row)| {
        let r0 = &input.data[(2 * y + 1) * in_row_len..(2 * y + 2) * in_row_len];
        let r1 = &input.data[(2 * y + 2) * in_row_len..(2 * y + 3) * in_row_len];
        pool_row(r0, r1, w, c, row);
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_core::Rng;

    /// Naive six-loop reference straight from the definition (OIHW kernel, zero padding).
    fn naive(input: &Padded, cout: usize, oihw: &[f32], bias: &[f32]) -> Vec<f32> {
        let (h, w, cin) = (input.h as isize, input.w as isize, input.c);
        let mut out = vec![0f32; (h * w) as usize * cout];
        for y in 0..h {
            for x in 0..w {
                for co in 0..cout {
                    let mut s = bias[co] as f64;
                    for ci in 0..cin {
                        for ky in 0..3isize {
                            for kx in 0..3isize {
                                let (yy, xx) = (y + ky - 1, x + kx - 1);
                                if yy < 0 || xx < 0 || yy >= h || xx >= w {
                                    continue;
                                }
                                let v = input.get(yy as usize, xx as usize, ci) as f64;
                                let k = oihw[((co * cin + ci) * 3 + ky as usize) * 3 + kx as usize];
                                s += v * k as f64;
                            }
                        }
                    }
                    out[((y * w + x) as usize) * cout + co] = s.max(0.0) as f32;
                }
            }
        }
        out
    }

    fn random_padded(h: usize, w: usize, c: usize, rng: &mut Rng) -> Padded {
        let mut p = Padded::zeros(h, w, c);
        for y in 0..h {
            for x in 0..w {
                for ch in 0..c {
                    let i = ((y + 1) * (w + 2) + x + 1) * c + ch;
                    p.data[i] = rng.normal() as f32;
                }
            }
        }
        p
    }

    #[test]
    fn both_algorithms_match_the_naive_definition() {
        let mut rng = Rng::new(7);
        // Sizes exercise every pixel tail (w mod 6) and one-row / one-column images.
        for &(h, w, cin, cout) in &[(5, 13, 3, 16), (4, 7, 20, 32), (1, 1, 8, 16), (3, 12, 64, 16), (2, 9, 5, 48)] {
            let input = random_padded(h, w, cin, &mut rng);
            let kernel: Vec<f32> = (0..cout * cin * 9).map(|_| 0.3 * rng.normal() as f32).collect();
            let bias: Vec<f32> = (0..cout).map(|_| 0.2 * rng.normal() as f32).collect();
            let conv = PreparedConv::new(cout, cin, &kernel, &bias);
            let want = naive(&input, cout, &kernel, &bias);
            for alg in [ConvAlgorithm::Direct, ConvAlgorithm::Im2colGemm] {
                let got = conv.forward(&input, alg);
                let got_int = got.interior();
                let max_err = got_int.iter().zip(&want).map(|(a, b)| (a - b).abs()).fold(0f32, f32::max);
                assert!(max_err < 1e-4, "{alg:?} {h}x{w}x{cin}->{cout}: max err {max_err}");
                // The border stays zero (the next layer's padding).
                let pw = w + 2;
                for y in 0..h + 2 {
                    for x in 0..pw {
                        if y == 0 || x == 0 || y == h + 1 || x == w + 1 {
                            assert!(got.data[(y * pw + x) * cout..(y * pw + x + 1) * cout].iter().all(|&v| v == 0.0));
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn portable_kernel_matches_naive_too() {
        let mut rng = Rng::new(3);
        let (h, w, cin, cout) = (3, 8, 6, 16);
        let input = random_padded(h, w, cin, &mut rng);
        let kernel: Vec<f32> = (0..cout * cin * 9).map(|_| rng.normal() as f32).collect();
        let bias = vec![0.1f32; cout];
        let conv = PreparedConv::new(cout, cin, &kernel, &bias);
        let want = naive(&input, cout, &kernel, &bias);
        let mut out = Padded::zeros(h, w, cout);
        let row_len = out.row_len();
        for y in 0..h {
            let row = &mut out.data[(y + 1) * row_len..(y + 2) * row_len];
            let inp = &input.data[y * input.row_len()..(y + 3) * input.row_len()];
            let mut x = 0;
            while x < w {
                let n = PX_BLOCK.min(w - x);
                direct_block(false, n, inp, input.row_len(), x * cin, cin, &conv.direct_kernel, &conv.bias, row, (x + 1) * cout, cout);
                x += n;
            }
        }
        let err = out.interior().iter().zip(&want).map(|(a, b)| (a - b).abs()).fold(0f32, f32::max);
        assert!(err < 1e-4, "{err}");
    }

    #[test]
    fn max_pool_floors_odd_sizes() {
        let mut p = Padded::zeros(3, 5, 2);
        for y in 0..3 {
            for x in 0..5 {
                for c in 0..2 {
                    p.data[((y + 1) * 7 + x + 1) * 2 + c] = (y * 10 + x) as f32 * if c == 0 { 1.0 } else { -1.0 };
                }
            }
        }
        let q = max_pool2(&p);
        assert_eq!((q.h, q.w), (1, 2));
        assert_eq!(q.get(0, 0, 0), 11.0);
        assert_eq!(q.get(0, 1, 0), 13.0);
        assert_eq!(q.get(0, 0, 1), 0.0);
        assert_eq!(q.get(0, 1, 1), -2.0);
    }
}
