//! The inference-only VGG16 trunk (torchvision `features[0..16]`): conv1_1, conv1_2, pool,
//! conv2_1, conv2_2, pool, conv3_1, conv3_2, conv3_3, every conv 3×3 / pad 1 / + bias / ReLU,
//! pools 2×2 stride 2 (floor), input normalised as torchvision ImageNet.

use crate::conv::{ConvAlgorithm, Padded, PreparedConv, fused_block};
use crate::error::{FeatureError, Result};
use crate::map::{FeatureMap, StoragePrecision};
use crate::weights::VggWeights;
use gs_core::Image;

/// Which VGG16 activation serves as F (docs/method.md §L_f).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FeatureLevel {
    /// conv2_2 + ReLU: 128 channels at 1/2 resolution (the default).
    #[default]
    Conv2_2,
    /// conv3_3 + ReLU: 256 channels at 1/4 resolution.
    Conv3_3,
}

gs_core::named_choices!(FeatureLevel, "feature layer", { FeatureLevel::Conv2_2 => "conv2_2", FeatureLevel::Conv3_3 => "conv3_3" });

impl FeatureLevel {
    /// Channels of the level's activation.
    pub fn channels(self) -> usize {
        match self {
            Self::Conv2_2 => 128,
            Self::Conv3_3 => 256,
        }
    }
    /// Image pixels per feature pixel.
    pub fn stride(self) -> usize {
        match self {
            Self::Conv2_2 => 2,
            Self::Conv3_3 => 4,
        }
    }
    /// Number of conv layers run.
    pub(crate) fn conv_layers(self) -> usize {
        match self {
            Self::Conv2_2 => 4,
            Self::Conv3_3 => 7,
        }
    }
    /// Feature-map size `(W', H')` for an image of `width × height` (floor pooling).
    pub fn output_size(self, width: usize, height: usize) -> (usize, usize) {
        (width / self.stride(), height / self.stride())
    }
}

/// Largest accepted input (width × height). Peak memory is about 2 × 64 channels × 4 B per
/// input pixel plus the output (≈ 0.6 KB/pixel): 8 MP ≈ 5 GB. Larger images must be
/// downscaled first (training images are, as in 3DGS).
pub const DEFAULT_MAX_PIXELS: usize = 8 << 20;

/// Options of one extraction.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtractOptions {
    /// Activation used as F.
    pub level: FeatureLevel,
    /// Convolution algorithm (results agree to f32 rounding).
    pub algorithm: ConvAlgorithm,
    /// Storage of the returned map (f16 halves the cache).
    pub precision: StoragePrecision,
    /// Optional channel reduction by a fixed seeded Gaussian random projection to this many
    /// channels (Johnson–Lindenstrauss: dot products and so cosines are preserved in
    /// expectation; the projected features can be negative, and they stay comparable across
    /// views because every view uses the same matrix). `None` keeps all channels.
    pub reduce_to: Option<usize>,
    /// Seed of the projection matrix.
    pub reduce_seed: u64,
    /// Input size cap (width × height) → a clear error instead of an out-of-memory kill.
    pub max_pixels: usize,
}

impl Default for ExtractOptions {
    fn default() -> Self {
        Self {
            level: FeatureLevel::Conv2_2,
            algorithm: ConvAlgorithm::default(),
            precision: StoragePrecision::F32,
            reduce_to: None,
            reduce_seed: 0x5EED_F00D,
            max_pixels: DEFAULT_MAX_PIXELS,
        }
    }
}

impl ExtractOptions {
    /// Default options at `level`.
    pub fn at(level: FeatureLevel) -> Self {
        Self { level, ..Self::default() }
    }

    /// Bytes of one cached feature map for a `width × height` image (the cache budget):
    /// W'·H'·C·(4 or 2). conv2_2 at 800×600: 400·300·128·4 B = 61.4 MB (f16: 30.7 MB);
    /// conv3_3: 200·150·256·4 B = 30.7 MB (f16: 15.4 MB).
    pub fn bytes_per_image(&self, width: usize, height: usize) -> usize {
        let (w, h) = self.level.output_size(width, height);
        let c = self.reduce_to.unwrap_or(self.level.channels());
        let b = match self.precision {
            StoragePrecision::F32 => 4,
            StoragePrecision::F16 => 2,
        };
        w * h * c * b
    }
}

/// The VGG16 feature extractor f(·) with its weights prepared for both conv algorithms.
#[derive(Debug, Clone)]
pub struct Vgg16 {
    mean: [f32; 3],
    std: [f32; 3],
    layers: Vec<PreparedConv>,
}

impl Vgg16 {
    /// The network with the bundled ImageNet weights (checksum verified).
    pub fn bundled() -> Result<Self> {
        Ok(Self::from_weights(&VggWeights::bundled()?))
    }

    /// The network from decoded weights.
    pub fn from_weights(w: &VggWeights) -> Self {
        let layers =
            w.layers.iter().map(|l| PreparedConv::new(l.cout, l.cin, &l.kernel, &l.bias)).collect();
        Self { mean: w.mean, std: w.std, layers }
    }

    /// Floating-point operations (2 × multiply-accumulates) of the convs up to `level` for a
    /// `width × height` image (pools and ReLUs not counted).
    pub fn flops(&self, width: usize, height: usize, level: FeatureLevel) -> u64 {
        let (mut w, mut h) = (width, height);
        let mut total = 0;
        for (i, l) in self.layers.iter().take(level.conv_layers()).enumerate() {
            if i == 2 || i == 4 {
                w /= 2;
                h /= 2;
            }
            total += 2 * l.macs(h, w);
        }
        total
    }

    /// F = f(I) at `level` with default options.
    pub fn extract(&self, image: &Image, level: FeatureLevel) -> Result<FeatureMap> {
        self.extract_with(image, &ExtractOptions::at(level))
    }

    /// F = f(I) with explicit options. The image must be RGB (3 channels, values nominally in
    /// [0, 1]; a 1-channel image is replicated to grey RGB), finite, at least `stride` pixels
    /// in each direction and at most `max_pixels` pixels.
    pub fn extract_with(&self, image: &Image, opts: &ExtractOptions) -> Result<FeatureMap> {
        let act = self.forward(image, opts)?;
        finish_map(act, opts)
    }

    /// Runs the network; returns the padded activation of `opts.level`.
    pub(crate) fn forward(&self, image: &Image, opts: &ExtractOptions) -> Result<Padded> {
        let mut x = self.input(image, opts)?;
        let l = &self.layers;
        let alg = opts.algorithm;
        // Blocks 1 and 2 run strip-fused (no full-resolution intermediates); block 3 works at
        // 1/4 resolution where whole-tensor layers are cheap in memory.
        x = fused_block(&x, &l[0], &l[1], true, alg);
        x = fused_block(&x, &l[2], &l[3], opts.level == FeatureLevel::Conv3_3, alg);
        if opts.level == FeatureLevel::Conv3_3 {
            for layer in &l[4..7] {
                x = layer.forward(&x, alg);
            }
        }
        Ok(x)
    }

    /// The conv layers, conv1_1 first.
    #[cfg(feature = "wgpu")]
    pub(crate) fn layers(&self) -> &[PreparedConv] {
        &self.layers
    }

    /// The network's input: `image` checked (channels, size, cap, finite values, `reduce_to`)
    /// and normalised as torchvision ImageNet, with a zero border.
    pub(crate) fn input(&self, image: &Image, opts: &ExtractOptions) -> Result<Padded> {
        let (w, h, ch) = (image.width(), image.height(), image.channels());
        if ch != 3 && ch != 1 {
            return Err(FeatureError::InvalidImage(format!(
                "{w}x{h} image has {ch} channels; the network takes RGB (3) or grey (1)"
            )));
        }
        let s = opts.level.stride();
        if w < s || h < s {
            return Err(FeatureError::InvalidImage(format!(
                "{w}x{h} image is smaller than the {s}-pixel stride of {:?}",
                opts.level
            )));
        }
        if w.saturating_mul(h) > opts.max_pixels {
            return Err(FeatureError::InvalidImage(format!(
                "{w}x{h} image exceeds the cap of {} pixels (downscale it first)",
                opts.max_pixels
            )));
        }
        if let Some(i) = image.data().iter().position(|v| !v.is_finite()) {
            return Err(FeatureError::InvalidImage(format!(
                "{w}x{h} image has a non-finite value at pixel ({}, {})",
                (i / ch) % w,
                i / ch / w
            )));
        }
        if let Some(d) = opts.reduce_to {
            if d == 0 || d > opts.level.channels() {
                return Err(FeatureError::InvalidParameter(format!(
                    "reduce_to = {d} must be in 1..={}",
                    opts.level.channels()
                )));
            }
        }
        let mut x = Padded::zeros(h, w, 3);
        let row_len = x.row_len();
        for y in 0..h {
            let src = image.row(y);
            let dst = &mut x.data[(y + 1) * row_len + 3..(y + 1) * row_len + 3 + 3 * w];
            for (px, out) in dst.chunks_exact_mut(3).enumerate() {
                for c in 0..3 {
                    let v = if ch == 3 { src[px * 3 + c] } else { src[px] };
                    out[c] = (v - self.mean[c]) / self.std[c];
                }
            }
        }
        Ok(x)
    }
}

/// The feature map of the activation `act` at `opts.level`: its interior, projected to
/// `opts.reduce_to` channels when asked, stored at `opts.precision`.
pub(crate) fn finish_map(act: Padded, opts: &ExtractOptions) -> Result<FeatureMap> {
    let stride = opts.level.stride() as f32;
    let mut map = FeatureMap::from_vec(act.w, act.h, act.c, stride, act.interior())?;
    if let Some(d) = opts.reduce_to {
        map = project_channels(&map, d, opts.reduce_seed)?;
    }
    Ok(map.with_precision(opts.precision))
}

/// The fixed seeded projection `[C][D]` (entries N(0, 1/D)) applied as F' = F·P.
pub fn projection_matrix(c: usize, d: usize, seed: u64) -> Vec<f32> {
    let mut rng = gs_core::Rng::new(seed);
    let scale = (1.0 / d as f32).sqrt();
    (0..c * d).map(|_| rng.normal() * scale).collect()
}

/// Reduces `map` to `d` channels with [`projection_matrix`].
fn project_channels(map: &FeatureMap, d: usize, seed: u64) -> Result<FeatureMap> {
    let (w, h, c) = (map.width(), map.height(), map.channels());
    let p = projection_matrix(c, d, seed);
    let src = map.to_f32_vec();
    let mut out = vec![0f32; w * h * d];
    let m = w * h;
    // SAFETY: src is m×c, p is c×d, out is m×d, row-major, non-overlapping.
    unsafe {
        matrixmultiply::sgemm(
            m,
            c,
            d,
            1.0,
            src.as_ptr(),
            c as isize,
            1,
            p.as_ptr(),
            d as isize,
            1,
            0.0,
            out.as_mut_ptr(),
            d as isize,
            1,
        );
    }
    FeatureMap::from_vec(w, h, d, map.stride(), out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise_image(w: usize, h: usize, seed: u64) -> Image {
        let mut rng = gs_core::Rng::new(seed);
        let d = (0..w * h * 3).map(|_| rng.uniform() as f32).collect();
        Image::from_vec(w, h, 3, d).unwrap()
    }

    #[test]
    fn shapes_strides_and_flops() {
        let net = Vgg16::bundled().unwrap();
        let img = noise_image(21, 14, 1);
        let f2 = net.extract(&img, FeatureLevel::Conv2_2).unwrap();
        assert_eq!((f2.width(), f2.height(), f2.channels(), f2.stride()), (10, 7, 128, 2.0));
        let f3 = net.extract(&img, FeatureLevel::Conv3_3).unwrap();
        assert_eq!((f3.width(), f3.height(), f3.channels(), f3.stride()), (5, 3, 256, 4.0));
        assert!(f3.to_f32_vec().iter().all(|v| v.is_finite() && *v >= 0.0));
        // The anchor's count: 90.1 GFLOP for conv2_2 at 800×600.
        assert_eq!(net.flops(800, 600, FeatureLevel::Conv2_2), 90_132_480_000);
        assert_eq!(
            net.flops(800, 600, FeatureLevel::Conv3_3),
            90_132_480_000 + 2 * 200 * 150 * 9 * (128 * 256 + 2 * 256 * 256)
        );
    }

    #[test]
    fn algorithms_agree_on_the_real_network() {
        let net = Vgg16::bundled().unwrap();
        let img = noise_image(19, 13, 2);
        let mut o = ExtractOptions::at(FeatureLevel::Conv3_3);
        o.algorithm = ConvAlgorithm::Direct;
        let a = net.extract_with(&img, &o).unwrap().to_f32_vec();
        o.algorithm = ConvAlgorithm::Im2colGemm;
        let b = net.extract_with(&img, &o).unwrap().to_f32_vec();
        let scale = a.iter().fold(0f32, |m, v| m.max(v.abs()));
        let err = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0f32, f32::max);
        assert!(scale > 1.0 && err < 1e-4 * scale, "err {err} scale {scale}");
    }

    #[test]
    fn fused_blocks_equal_layer_by_layer() {
        use crate::conv::max_pool2;
        let net = Vgg16::bundled().unwrap();
        // 37 rows: several strips with a ragged last one; odd sizes exercise floor pooling.
        let img = noise_image(23, 37, 5);
        for level in [FeatureLevel::Conv2_2, FeatureLevel::Conv3_3] {
            for alg in [ConvAlgorithm::Direct, ConvAlgorithm::Im2colGemm] {
                let opts = ExtractOptions { algorithm: alg, ..ExtractOptions::at(level) };
                let fused = net.forward(&img, &opts).unwrap();
                let mut x = Padded::zeros(img.height(), img.width(), 3);
                let rl = x.row_len();
                for y in 0..img.height() {
                    for px in 0..img.width() {
                        for c in 0..3 {
                            x.data[(y + 1) * rl + (px + 1) * 3 + c] =
                                (img.get(px, y, c) - net.mean[c]) / net.std[c];
                        }
                    }
                }
                for (i, layer) in net.layers.iter().take(level.conv_layers()).enumerate() {
                    if i == 2 || i == 4 {
                        x = max_pool2(&x);
                    }
                    x = layer.forward(&x, alg);
                }
                assert_eq!(fused, x, "{level:?} {alg:?}");
            }
        }
    }

    #[test]
    fn deterministic_across_thread_counts() {
        let net = Vgg16::bundled().unwrap();
        let img = noise_image(24, 10, 3);
        let run = |t| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap();
            pool.install(|| net.extract(&img, FeatureLevel::Conv2_2).unwrap())
        };
        assert_eq!(run(1), run(2));
    }

    #[test]
    fn invalid_inputs_are_clear_errors() {
        let net = Vgg16::bundled().unwrap();
        let e = |r: Result<FeatureMap>| r.unwrap_err().to_string();
        assert!(e(net.extract(&Image::new(1, 1, 3).unwrap(), FeatureLevel::Conv2_2)).contains("smaller"));
        assert!(e(net.extract(&Image::new(3, 3, 3).unwrap(), FeatureLevel::Conv3_3)).contains("smaller"));
        assert!(e(net.extract(&Image::new(8, 8, 4).unwrap(), FeatureLevel::Conv2_2)).contains("4 channels"));
        let mut nan = Image::new(8, 8, 3).unwrap();
        nan.set(5, 2, 1, f32::NAN);
        assert!(e(net.extract(&nan, FeatureLevel::Conv2_2)).contains("(5, 2)"));
        let mut o = ExtractOptions::default();
        o.max_pixels = 100;
        assert!(e(net.extract_with(&Image::new(20, 20, 3).unwrap(), &o)).contains("cap"));
        o = ExtractOptions { reduce_to: Some(0), ..Default::default() };
        assert!(e(net.extract_with(&Image::new(8, 8, 3).unwrap(), &o)).contains("reduce_to"));
        o.reduce_to = Some(129);
        assert!(e(net.extract_with(&Image::new(8, 8, 3).unwrap(), &o)).contains("reduce_to"));
        // Extremes that are valid: constant, saturated, grey.
        for v in [0.0, 1.0] {
            let f = net.extract(&Image::filled(6, 4, 3, v).unwrap(), FeatureLevel::Conv3_3).unwrap();
            assert!(f.to_f32_vec().iter().all(|x| x.is_finite()));
        }
        let grey = net.extract(&Image::filled(6, 4, 1, 0.5).unwrap(), FeatureLevel::Conv2_2).unwrap();
        let rgb = net.extract(&Image::filled(6, 4, 3, 0.5).unwrap(), FeatureLevel::Conv2_2).unwrap();
        assert_eq!(grey, rgb);
    }

    #[test]
    fn projection_reduces_channels_and_roughly_keeps_cosines() {
        let net = Vgg16::bundled().unwrap();
        let img = noise_image(32, 24, 4);
        let full = net.extract(&img, FeatureLevel::Conv2_2).unwrap();
        let o = ExtractOptions { reduce_to: Some(64), ..Default::default() };
        let red = net.extract_with(&img, &o).unwrap();
        assert_eq!(red.channels(), 64);
        assert_eq!(red, net.extract_with(&img, &o).unwrap(), "fixed seed → same matrix");
        let (mut a, mut b) = (vec![0f32; 128], vec![0f32; 128]);
        let (mut ra, mut rb) = (vec![0f32; 64], vec![0f32; 64]);
        let mut err = 0f32;
        let mut n = 0;
        for y in 0..12 {
            for x in 0..15 {
                full.pixel_into(x, y, &mut a);
                full.pixel_into(x + 1, y, &mut b);
                red.pixel_into(x, y, &mut ra);
                red.pixel_into(x + 1, y, &mut rb);
                err += (crate::cosine(&a, &b) - crate::cosine(&ra, &rb)).abs();
                n += 1;
            }
        }
        assert!(err / (n as f32) < 0.1, "mean cosine change {}", err / n as f32);
    }
}
