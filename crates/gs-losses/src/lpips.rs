//! LPIPS (Zhang et al. 2018), AlexNet backbone, linear heads v0.1 — the image metric of
//! docs/method.md §Metrics.
//!
//! The weights (torchvision ImageNet AlexNet convs + LPIPS v0.1 heads, from
//! `shared/weights/lpips_alex_v0.1.npz`) are bundled in `weights/lpips_alex_v0.1.f16.bin`: conv
//! weights in IEEE half, everything else f32, with a size and FNV-1a-64 check on load
//! (`scripts/lpips_weights_to_f16.py` writes it). Forward pass: x ∈ \[0,1\] → 2x − 1 →
//! (x − shift)/scale → conv1 (11×11/4, pad 2) → ReLU → tap1 → maxpool 3/2 → conv2 (5×5, pad 2) →
//! ReLU → tap2 → maxpool 3/2 → conv3 → ReLU → tap3 → conv4 → ReLU → tap4 → conv5 → ReLU → tap5;
//! per tap: unit-normalise over channels (f / (‖f‖ + 1e-10)), squared difference, 1×1 linear head,
//! spatial mean; LPIPS = sum over the five taps. Convolutions are im2col + `matrixmultiply`
//! sgemm, parallel over column blocks with rayon (deterministic).

use crate::error::{LossError, Result};
use gs_core::half::f16_to_f32;
use gs_core::Image;
use rayon::prelude::*;
use std::path::Path;

const MAGIC: &[u8; 8] = b"VGSLPW01";
/// The bundled weights file.
static BUNDLED: &[u8] = include_bytes!("../weights/lpips_alex_v0.1.f16.bin");
/// Size of the bundled file in bytes (checked on load).
pub const BUNDLED_SIZE: usize = 4_946_778;

/// (name, shape) of every tensor the file must hold, in order.
fn expected() -> Vec<(String, Vec<usize>)> {
    let convs = [
        (64, 3, 11),
        (192, 64, 5),
        (384, 192, 3),
        (256, 384, 3),
        (256, 256, 3),
    ];
    let mut v = Vec::new();
    for (i, &(o, c, k)) in convs.iter().enumerate() {
        v.push((format!("conv{}_weight", i + 1), vec![o, c, k, k]));
        v.push((format!("conv{}_bias", i + 1), vec![o]));
    }
    for (i, &(o, _, _)) in convs.iter().enumerate() {
        v.push((format!("lin{i}_weight"), vec![1, o, 1, 1]));
    }
    v.push(("scaling_shift".into(), vec![3]));
    v.push(("scaling_scale".into(), vec![3]));
    v
}

/// FNV-1a, 64 bit.
fn fnv1a64(data: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in data {
        h ^= b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

#[derive(Debug, Clone)]
struct Conv {
    out_c: usize,
    in_c: usize,
    k: usize,
    stride: usize,
    pad: usize,
    weight: Vec<f32>, // [O][I][k][k]
    bias: Vec<f32>,
}

/// A CHW feature map.
#[derive(Debug, Clone)]
struct Tensor {
    c: usize,
    h: usize,
    w: usize,
    data: Vec<f32>,
}

/// The LPIPS-alex v0.1 model.
#[derive(Debug, Clone)]
pub struct Lpips {
    convs: Vec<Conv>,
    lins: Vec<Vec<f32>>,
    shift: [f32; 3],
    scale: [f32; 3],
}

impl Lpips {
    /// The model with the weights bundled in the crate.
    pub fn bundled() -> Result<Self> {
        Self::from_bytes(
            BUNDLED,
            "bundled weights/lpips_alex_v0.1.f16.bin",
            Some(BUNDLED_SIZE),
        )
    }

    /// Loads a weights file in the bundled format.
    pub fn from_file(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| LossError::Weights {
            file: path.display().to_string(),
            problem: e.to_string(),
        })?;
        Self::from_bytes(&bytes, &path.display().to_string(), None)
    }

    /// Parses weights from bytes; `name` is used in errors, `size` (when given) must match exactly.
    pub fn from_bytes(bytes: &[u8], name: &str, size: Option<usize>) -> Result<Self> {
        let err = |problem: String| LossError::Weights {
            file: name.to_string(),
            problem,
        };
        if let Some(s) = size
            && bytes.len() != s
        {
            return Err(err(format!("{} bytes, expected {s}", bytes.len())));
        }
        if bytes.len() < 20 || &bytes[..8] != MAGIC {
            return Err(err(
                "wrong magic (not a gs-losses LPIPS weights file)".into()
            ));
        }
        let (body, tail) = bytes.split_at(bytes.len() - 8);
        let stored = u64::from_le_bytes(tail.try_into().expect("8 bytes"));
        let actual = fnv1a64(body);
        if stored != actual {
            return Err(err(format!(
                "checksum mismatch: stored {stored:016x}, computed {actual:016x}"
            )));
        }
        let mut pos = 8;
        let mut take = |n: usize| -> Result<&[u8]> {
            let s = body
                .get(pos..pos + n)
                .ok_or_else(|| err("truncated".into()))?;
            pos += n;
            Ok(s)
        };
        let count = u32::from_le_bytes(take(4)?.try_into().expect("4 bytes")) as usize;
        let exp = expected();
        if count != exp.len() {
            return Err(err(format!("{count} tensors, expected {}", exp.len())));
        }
        let mut tensors = Vec::with_capacity(count);
        for (ename, eshape) in &exp {
            let nl = take(1)?[0] as usize;
            let tname = String::from_utf8_lossy(take(nl)?).to_string();
            let hdr = take(2)?;
            let (dtype, ndim) = (hdr[0], hdr[1] as usize);
            let mut shape = Vec::with_capacity(ndim);
            for _ in 0..ndim {
                shape.push(u32::from_le_bytes(take(4)?.try_into().expect("4 bytes")) as usize);
            }
            if &tname != ename || &shape != eshape {
                return Err(err(format!(
                    "tensor {tname} {shape:?}, expected {ename} {eshape:?}"
                )));
            }
            let n: usize = shape.iter().product();
            let data: Vec<f32> = match dtype {
                0 => take(4 * n)?
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes(c.try_into().expect("4")))
                    .collect(),
                1 => take(2 * n)?
                    .chunks_exact(2)
                    .map(|c| f16_to_f32(u16::from_le_bytes([c[0], c[1]])))
                    .collect(),
                d => return Err(err(format!("tensor {tname}: unknown dtype {d}"))),
            };
            if data.iter().any(|v| !v.is_finite()) {
                return Err(err(format!("tensor {tname} has non-finite values")));
            }
            tensors.push(data);
        }
        if pos != body.len() {
            return Err(err(format!("{} trailing bytes", body.len() - pos)));
        }
        let mut it = tensors.into_iter();
        let geo = [(4, 2), (1, 2), (1, 1), (1, 1), (1, 1)];
        let mut convs = Vec::new();
        for (i, &(stride, pad)) in geo.iter().enumerate() {
            let weight = it.next().expect("weight");
            let bias = it.next().expect("bias");
            let s = &exp[2 * i].1;
            convs.push(Conv {
                out_c: s[0],
                in_c: s[1],
                k: s[2],
                stride,
                pad,
                weight,
                bias,
            });
        }
        let lins: Vec<Vec<f32>> = (0..5).map(|_| it.next().expect("lin")).collect();
        let sh = it.next().expect("shift");
        let sc = it.next().expect("scale");
        if sc.contains(&0.0) {
            return Err(err("scaling_scale has a zero".into()));
        }
        Ok(Self {
            convs,
            lins,
            shift: [sh[0], sh[1], sh[2]],
            scale: [sc[0], sc[1], sc[2]],
        })
    }

    /// Smallest accepted input side (the fifth tap must be at least 1×1).
    pub const MIN_SIDE: usize = 31;

    /// LPIPS distance of two RGB images with values in [0, 1] (same size, ≥ 31×31); symmetric,
    /// 0 for identical images.
    pub fn distance(&self, a: &Image, b: &Image) -> Result<f64> {
        Ok(self.distance_per_layer(a, b)?.iter().sum())
    }

    /// The five per-tap terms (lin0..lin4) whose sum is the distance.
    pub fn distance_per_layer(&self, a: &Image, b: &Image) -> Result<[f64; 5]> {
        for (n, img) in [("first", a), ("second", b)] {
            if img.channels() != 3 {
                return Err(LossError::Channels(format!(
                    "LPIPS needs RGB images, the {n} has {} channels",
                    img.channels()
                )));
            }
            if img.width() < Self::MIN_SIDE || img.height() < Self::MIN_SIDE {
                return Err(LossError::InvalidParameter(format!(
                    "LPIPS needs images of at least {0}×{0} pixels, the {n} is {1}×{2}",
                    Self::MIN_SIDE,
                    img.width(),
                    img.height()
                )));
            }
            if !img.is_finite() {
                return Err(LossError::InvalidParameter(format!(
                    "the {n} image has non-finite values"
                )));
            }
        }
        if a.width() != b.width() || a.height() != b.height() {
            return Err(LossError::ShapeMismatch(format!(
                "LPIPS images are {}×{} and {}×{}",
                a.width(),
                a.height(),
                b.width(),
                b.height()
            )));
        }
        let fa = self.features(a);
        let fb = self.features(b);
        let mut out = [0.0; 5];
        for (k, ((ta, tb), lin)) in fa.iter().zip(&fb).zip(&self.lins).enumerate() {
            out[k] = head(ta, tb, lin);
        }
        Ok(out)
    }

    fn features(&self, img: &Image) -> Vec<Tensor> {
        let (w, h) = (img.width(), img.height());
        let mut data = vec![0.0f32; 3 * w * h];
        for (p, px) in img.data().chunks_exact(3).enumerate() {
            for c in 0..3 {
                data[c * w * h + p] = (px[c] * 2.0 - 1.0 - self.shift[c]) / self.scale[c];
            }
        }
        let x = Tensor { c: 3, h, w, data };
        let t1 = conv_relu(&x, &self.convs[0]);
        let t2 = conv_relu(&maxpool3s2(&t1), &self.convs[1]);
        let t3 = conv_relu(&maxpool3s2(&t2), &self.convs[2]);
        let t4 = conv_relu(&t3, &self.convs[3]);
        let t5 = conv_relu(&t4, &self.convs[4]);
        vec![t1, t2, t3, t4, t5]
    }
}

/// Σ_c lin_c (f̂0 − f̂1)², averaged over the tap's pixels.
fn head(a: &Tensor, b: &Tensor, lin: &[f32]) -> f64 {
    let hw = a.h * a.w;
    let per: Vec<f64> = (0..hw)
        .into_par_iter()
        .map(|p| {
            let (mut na, mut nb) = (0.0f64, 0.0f64);
            for c in 0..a.c {
                na += (a.data[c * hw + p] as f64).powi(2);
                nb += (b.data[c * hw + p] as f64).powi(2);
            }
            let (ia, ib) = (1.0 / (na.sqrt() + 1e-10), 1.0 / (nb.sqrt() + 1e-10));
            (0..a.c)
                .map(|c| {
                    let d = a.data[c * hw + p] as f64 * ia - b.data[c * hw + p] as f64 * ib;
                    lin[c] as f64 * d * d
                })
                .sum()
        })
        .collect();
    per.iter().sum::<f64>() / hw as f64
}

fn maxpool3s2(x: &Tensor) -> Tensor {
    let ho = (x.h - 3) / 2 + 1;
    let wo = (x.w - 3) / 2 + 1;
    let mut data = vec![0.0f32; x.c * ho * wo];
    data.par_chunks_mut(ho * wo)
        .enumerate()
        .for_each(|(c, out)| {
            let src = &x.data[c * x.h * x.w..(c + 1) * x.h * x.w];
            for oy in 0..ho {
                for ox in 0..wo {
                    let mut m = f32::NEG_INFINITY;
                    for dy in 0..3 {
                        for dx in 0..3 {
                            m = m.max(src[(oy * 2 + dy) * x.w + ox * 2 + dx]);
                        }
                    }
                    out[oy * wo + ox] = m;
                }
            }
        });
    Tensor {
        c: x.c,
        h: ho,
        w: wo,
        data,
    }
}

/// Convolution + bias + ReLU: im2col per block of output pixels, then one sgemm per block.
fn conv_relu(x: &Tensor, l: &Conv) -> Tensor {
    debug_assert_eq!(x.c, l.in_c);
    let ho = (x.h + 2 * l.pad - l.k) / l.stride + 1;
    let wo = (x.w + 2 * l.pad - l.k) / l.stride + 1;
    let m = ho * wo;
    let kk = l.in_c * l.k * l.k;
    const BLOCK: usize = 256;
    let blocks: Vec<Vec<f32>> = (0..m.div_ceil(BLOCK))
        .into_par_iter()
        .map(|bi| {
            let m0 = bi * BLOCK;
            let nb = BLOCK.min(m - m0);
            let mut col = vec![0.0f32; kk * nb];
            for ci in 0..l.in_c {
                let src = &x.data[ci * x.h * x.w..(ci + 1) * x.h * x.w];
                for ky in 0..l.k {
                    for kx in 0..l.k {
                        let row = &mut col[((ci * l.k + ky) * l.k + kx) * nb..][..nb];
                        for (j, v) in row.iter_mut().enumerate() {
                            let o = m0 + j;
                            let (oy, ox) = (o / wo, o % wo);
                            let iy = (oy * l.stride + ky) as isize - l.pad as isize;
                            let ix = (ox * l.stride + kx) as isize - l.pad as isize;
                            if iy >= 0 && ix >= 0 && (iy as usize) < x.h && (ix as usize) < x.w {
                                *v = src[iy as usize * x.w + ix as usize];
                            }
                        }
                    }
                }
            }
            let mut out = vec![0.0f32; l.out_c * nb];
            // SAFETY: the slices have exactly the lengths implied by the dimensions and strides:
            // weight is out_c × kk (row-major), col is kk × nb, out is out_c × nb.
            unsafe {
                matrixmultiply::sgemm(
                    l.out_c,
                    kk,
                    nb,
                    1.0,
                    l.weight.as_ptr(),
                    kk as isize,
                    1,
                    col.as_ptr(),
                    nb as isize,
                    1,
                    0.0,
                    out.as_mut_ptr(),
                    nb as isize,
                    1,
                );
            }
            out
        })
        .collect();
    let mut data = vec![0.0f32; l.out_c * m];
    data.par_chunks_mut(m).enumerate().for_each(|(o, dst)| {
        let b = l.bias[o];
        for (bi, blk) in blocks.iter().enumerate() {
            let m0 = bi * BLOCK;
            let nb = BLOCK.min(m - m0);
            for (d, &s) in dst[m0..m0 + nb].iter_mut().zip(&blk[o * nb..(o + 1) * nb]) {
                *d = (s + b).max(0.0);
            }
        }
    });
    Tensor {
        c: l.out_c,
        h: ho,
        w: wo,
        data,
    }
}
