//! The bundled VGG16 weight blob: f16 conv kernels + f32 biases, a shape header and a CRC-32.
//!
//! Layout (little-endian; written by `scripts/convert_vgg16_weights.py`):
//! magic `b"VGGF16\0\x01"`, version u32 = 1, layer count u32 = 7, input mean 3×f32, input std
//! 3×f32, then per layer a 16-byte zero-padded name and (cout, cin, kh, kw) as u32, then per
//! layer its OIHW kernel as f16 followed by its bias as f32, and finally the zlib CRC-32 of every
//! preceding byte. The loader checks magic, version, names, shapes, total size and checksum,
//! so a truncated or corrupted blob is a clear [`FeatureError::CorruptWeights`].

use crate::error::{FeatureError, Result};

/// The bundled blob (torchvision VGG16 IMAGENET1K_V1, conv1_1..conv3_3, kernels rounded to f16).
pub static BUNDLED_VGG16_BLOB: &[u8] = include_bytes!("../weights/vgg16_conv3_3.f16.bin");

const MAGIC: &[u8; 8] = b"VGGF16\0\x01";
const VERSION: u32 = 1;
/// Layer names in network order.
pub const LAYER_NAMES: [&str; 7] =
    ["conv1_1", "conv1_2", "conv2_1", "conv2_2", "conv3_1", "conv3_2", "conv3_3"];
/// (cout, cin) of every layer, as torchvision's VGG16.
pub const LAYER_SHAPES: [(usize, usize); 7] =
    [(64, 3), (64, 64), (128, 64), (128, 128), (256, 128), (256, 256), (256, 256)];

/// One 3×3 convolution layer as stored: OIHW kernel (f32, decoded from f16) and bias.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvWeights {
    /// Layer name (`conv1_1` …).
    pub name: String,
    /// Output channels.
    pub cout: usize,
    /// Input channels.
    pub cin: usize,
    /// Kernel, OIHW `[cout][cin][3][3]`.
    pub kernel: Vec<f32>,
    /// Bias `[cout]`.
    pub bias: Vec<f32>,
}

/// All weights of the network plus its input normalisation.
#[derive(Debug, Clone, PartialEq)]
pub struct VggWeights {
    /// Per-channel input mean (RGB in [0, 1]), torchvision's (0.485, 0.456, 0.406).
    pub mean: [f32; 3],
    /// Per-channel input std, torchvision's (0.229, 0.224, 0.225).
    pub std: [f32; 3],
    /// conv1_1 … conv3_3.
    pub layers: Vec<ConvWeights>,
}

/// zlib / IEEE CRC-32 (reflected, polynomial 0xEDB88320).
pub fn crc32(bytes: &[u8]) -> u32 {
    static TABLE: std::sync::OnceLock<[u32; 256]> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        let mut t = [0u32; 256];
        for (i, e) in t.iter_mut().enumerate() {
            let mut c = i as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            }
            *e = c;
        }
        t
    });
    let mut c = !0u32;
    for &b in bytes {
        c = table[((c ^ b as u32) & 0xFF) as usize] ^ (c >> 8);
    }
    !c
}

pub use gs_core::half::{f16_to_f32, f32_to_f16};

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
    source: &'a str,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if self.bytes.len() - self.pos < n {
            return Err(corrupt(
                self.source,
                format!(
                    "truncated: {what} needs {n} bytes at offset {}, blob has {}",
                    self.pos,
                    self.bytes.len()
                ),
            ));
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().expect("4 bytes")))
    }
    fn f32(&mut self, what: &str) -> Result<f32> {
        Ok(f32::from_le_bytes(self.take(4, what)?.try_into().expect("4 bytes")))
    }
}

fn corrupt(source: &str, problem: String) -> FeatureError {
    FeatureError::CorruptWeights { source_name: source.to_string(), problem }
}

impl VggWeights {
    /// Decodes and verifies the bundled blob.
    pub fn bundled() -> Result<Self> {
        Self::from_blob(BUNDLED_VGG16_BLOB, "bundled vgg16_conv3_3.f16.bin")
    }

    /// Decodes and verifies a blob; `source` names it in errors.
    pub fn from_blob(bytes: &[u8], source: &str) -> Result<Self> {
        if bytes.len() < MAGIC.len() + 4 {
            return Err(corrupt(source, format!("only {} bytes", bytes.len())));
        }
        if &bytes[..8] != MAGIC {
            return Err(corrupt(source, "wrong magic (not a gs-features VGG16 blob)".into()));
        }
        let body = &bytes[..bytes.len() - 4];
        let stored = u32::from_le_bytes(bytes[bytes.len() - 4..].try_into().expect("4 bytes"));
        let mut r = Reader { bytes: body, pos: 8, source };
        let version = r.u32("version")?;
        if version != VERSION {
            return Err(corrupt(source, format!("version {version}, expected {VERSION}")));
        }
        let n = r.u32("layer count")? as usize;
        if n != LAYER_NAMES.len() {
            return Err(corrupt(source, format!("{n} layers, expected {}", LAYER_NAMES.len())));
        }
        let mut mean = [0f32; 3];
        let mut std = [0f32; 3];
        for m in &mut mean {
            *m = r.f32("input mean")?;
        }
        for s in &mut std {
            *s = r.f32("input std")?;
        }
        let mut shapes = Vec::with_capacity(n);
        for (i, name) in LAYER_NAMES.iter().enumerate() {
            let raw = r.take(16, "layer name")?;
            let stored_name: String =
                raw.iter().take_while(|&&b| b != 0).map(|&b| b as char).collect();
            if stored_name != *name {
                return Err(corrupt(source, format!("layer {i} is {stored_name:?}, expected {name}")));
            }
            let dims = [r.u32("cout")?, r.u32("cin")?, r.u32("kh")?, r.u32("kw")?];
            let (cout, cin) = LAYER_SHAPES[i];
            if dims != [cout as u32, cin as u32, 3, 3] {
                return Err(corrupt(
                    source,
                    format!("{name} has shape {dims:?}, expected [{cout}, {cin}, 3, 3]"),
                ));
            }
            shapes.push((cout, cin));
        }
        let payload: usize = shapes.iter().map(|&(co, ci)| co * ci * 9 * 2 + co * 4).sum();
        let expected = r.pos + payload + 4;
        if bytes.len() != expected {
            return Err(corrupt(
                source,
                format!("size {} bytes, the header implies {expected}", bytes.len()),
            ));
        }
        let actual = crc32(body);
        if actual != stored {
            return Err(corrupt(
                source,
                format!("checksum mismatch: stored crc32 {stored:08x}, computed {actual:08x}"),
            ));
        }
        if mean.iter().chain(std.iter()).any(|v| !v.is_finite()) || std.iter().any(|&s| s <= 0.0) {
            return Err(corrupt(source, format!("bad normalisation mean {mean:?} std {std:?}")));
        }
        let mut layers = Vec::with_capacity(n);
        for (i, &(cout, cin)) in shapes.iter().enumerate() {
            let kbytes = r.take(cout * cin * 9 * 2, "kernel")?;
            let kernel: Vec<f32> = kbytes
                .chunks_exact(2)
                .map(|c| f16_to_f32(u16::from_le_bytes([c[0], c[1]])))
                .collect();
            let bbytes = r.take(cout * 4, "bias")?;
            let bias: Vec<f32> = bbytes
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
                .collect();
            if kernel.iter().chain(bias.iter()).any(|v| !v.is_finite()) {
                return Err(corrupt(source, format!("{} holds non-finite values", LAYER_NAMES[i])));
            }
            layers.push(ConvWeights { name: LAYER_NAMES[i].to_string(), cout, cin, kernel, bias });
        }
        Ok(Self { mean, std, layers })
    }

    /// Reads and verifies a blob file.
    pub fn from_file(path: &std::path::Path) -> Result<Self> {
        let bytes = gs_io::capped::WEIGHTS.read(path).map_err(|e| FeatureError::Io {
            path: path.display().to_string(),
            message: match e {
                gs_io::IoError::Io { source, .. } => source.to_string(),
                gs_io::IoError::Invalid { message, .. } => message,
                other => other.to_string(),
            },
        })?;
        Self::from_blob(&bytes, &path.display().to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_over_the_weights_cap_is_refused_unread() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("w.bin");
        std::fs::File::create(&p).unwrap().set_len(gs_io::capped::WEIGHTS.bytes + 1).unwrap();
        let e = VggWeights::from_file(&p).unwrap_err().to_string();
        assert!(e.ends_with("w.bin: the file holds 64.0 MiB, more than the cap of 64 MiB for a weights file"), "{e}");
    }

    #[test]
    fn crc32_matches_zlib() {
        // zlib.crc32(b"123456789") == 0xCBF43926 (the standard check value).
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }


    #[test]
    fn bundled_blob_loads_with_torchvision_shapes_and_normalisation() {
        let w = VggWeights::bundled().unwrap();
        assert_eq!(w.layers.len(), 7);
        assert_eq!(w.mean, [0.485, 0.456, 0.406]);
        assert_eq!(w.std, [0.229, 0.224, 0.225]);
        for (l, &(co, ci)) in w.layers.iter().zip(LAYER_SHAPES.iter()) {
            assert_eq!(l.kernel.len(), co * ci * 9);
            assert_eq!(l.bias.len(), co);
        }
        assert_eq!(BUNDLED_VGG16_BLOB.len(), 3_473_548);
    }

    #[test]
    fn corrupt_blobs_give_clear_errors() {
        let good = BUNDLED_VGG16_BLOB;
        let msg = |b: &[u8]| match VggWeights::from_blob(b, "test.bin") {
            Err(FeatureError::CorruptWeights { source_name, problem }) => {
                assert_eq!(source_name, "test.bin");
                problem
            }
            other => panic!("expected CorruptWeights, got {other:?}"),
        };
        assert!(msg(&[]).contains("only 0 bytes"));
        assert!(msg(&good[..good.len() - 1000]).contains("size"));
        assert!(msg(&good[..40]).contains("truncated"));
        let mut flipped = good.to_vec();
        flipped[good.len() / 2] ^= 0x10;
        assert!(msg(&flipped).contains("checksum mismatch"));
        let mut magic = good.to_vec();
        magic[0] = b'X';
        assert!(msg(&magic).contains("magic"));
        let mut version = good.to_vec();
        version[8] = 2;
        assert!(msg(&version).contains("version 2"));
        let mut extended = good.to_vec();
        extended.push(0);
        assert!(msg(&extended).contains("size"));
        assert!(matches!(
            VggWeights::from_file(std::path::Path::new("/nonexistent/w.bin")),
            Err(FeatureError::Io { .. })
        ));
    }
}
