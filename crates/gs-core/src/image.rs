//! Row-major `[H][W][C]` f32 image buffers.
//!
//! Values are linear-in-file in `[0, 1]` (8-bit files read as value/255, no gamma
//! conversion, as every 3DGS implementation does). Continuous coordinates follow the
//! pixel-centre-at-0.5 convention of docs/architecture.md §Conventions.

use crate::error::{CoreError, Result};

/// Largest accepted width × height (a resource cap: 64 megapixels).
pub const MAX_IMAGE_PIXELS: usize = 64 << 20;

/// An f32 image with `channels` values per pixel, row-major `[H][W][C]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    width: usize,
    height: usize,
    channels: usize,
    data: Vec<f32>,
}

/// Luma weights used for grey images (ITU-R BT.601, as PGSR's `0.299R + 0.587G + 0.114B`).
pub const GREY_WEIGHTS: [f32; 3] = [0.299, 0.587, 0.114];

/// Why a flat buffer of `len` values is not a row-major `width × height × channels` grid
/// (`None` when it is): the one size check behind [`Image`] and the other crates' maps
/// (feature maps, reprojection views), each of which wraps the message in its own error.
pub fn grid_len_mismatch(width: usize, height: usize, channels: usize, len: usize) -> Option<String> {
    let need = width.checked_mul(height).and_then(|p| p.checked_mul(channels));
    (need != Some(len)).then(|| match need {
        Some(n) => format!("a {width}x{height}x{channels} grid needs {n} values, the buffer has {len}"),
        None => format!("a {width}x{height}x{channels} grid is too large to address"),
    })
}

impl Image {
    fn check_size(width: usize, height: usize, channels: usize) -> Result<()> {
        if width == 0 || height == 0 || channels == 0 {
            return Err(CoreError::InvalidImage(format!(
                "size {width}x{height}x{channels} is empty"
            )));
        }
        if width.checked_mul(height).is_none_or(|p| p > MAX_IMAGE_PIXELS) {
            return Err(CoreError::InvalidImage(format!(
                "size {width}x{height} exceeds the cap of {MAX_IMAGE_PIXELS} pixels"
            )));
        }
        Ok(())
    }

    /// A black image; an error for a zero or over-cap size.
    pub fn new(width: usize, height: usize, channels: usize) -> Result<Self> {
        Self::filled(width, height, channels, 0.0)
    }

    /// An image with every value set to `value`.
    pub fn filled(width: usize, height: usize, channels: usize, value: f32) -> Result<Self> {
        Self::check_size(width, height, channels)?;
        Ok(Self { width, height, channels, data: vec![value; width * height * channels] })
    }

    /// Wraps a row-major `[H][W][C]` buffer; an error when its length does not match.
    pub fn from_vec(width: usize, height: usize, channels: usize, data: Vec<f32>) -> Result<Self> {
        Self::check_size(width, height, channels)?;
        if let Some(m) = grid_len_mismatch(width, height, channels, data.len()) {
            return Err(CoreError::InvalidImage(m));
        }
        Ok(Self { width, height, channels, data })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Values per pixel.
    pub fn channels(&self) -> usize {
        self.channels
    }
    /// The whole buffer, row-major `[H][W][C]`.
    pub fn data(&self) -> &[f32] {
        &self.data
    }
    /// The whole buffer, mutable.
    pub fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }
    /// Consumes the image and returns its buffer.
    pub fn into_vec(self) -> Vec<f32> {
        self.data
    }

    /// Index of value `(x, y, c)` in the buffer.
    #[inline]
    pub fn index(&self, x: usize, y: usize, c: usize) -> usize {
        (y * self.width + x) * self.channels + c
    }

    /// Value at column `x`, row `y`, channel `c` (panics when out of range, like slice indexing).
    #[inline]
    pub fn get(&self, x: usize, y: usize, c: usize) -> f32 {
        self.data[self.index(x, y, c)]
    }

    /// Sets the value at column `x`, row `y`, channel `c`.
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, c: usize, value: f32) {
        let i = self.index(x, y, c);
        self.data[i] = value;
    }

    /// The `channels` values of pixel `(x, y)`.
    #[inline]
    pub fn pixel(&self, x: usize, y: usize) -> &[f32] {
        let i = self.index(x, y, 0);
        &self.data[i..i + self.channels]
    }

    /// The values of pixel `(x, y)`, mutable.
    #[inline]
    pub fn pixel_mut(&mut self, x: usize, y: usize) -> &mut [f32] {
        let i = self.index(x, y, 0);
        let c = self.channels;
        &mut self.data[i..i + c]
    }

    /// One row, `width × channels` values.
    pub fn row(&self, y: usize) -> &[f32] {
        let n = self.width * self.channels;
        &self.data[y * n..(y + 1) * n]
    }

    /// Whether every value is finite.
    pub fn is_finite(&self) -> bool {
        self.data.iter().all(|v| v.is_finite())
    }

    /// Grey image `0.299R + 0.587G + 0.114B` of an RGB(A) image; a copy of a 1-channel image.
    pub fn to_grey(&self) -> Result<Image> {
        match self.channels {
            1 => Ok(self.clone()),
            c if c >= 3 => {
                let data = self
                    .data
                    .chunks_exact(c)
                    .map(|p| GREY_WEIGHTS[0] * p[0] + GREY_WEIGHTS[1] * p[1] + GREY_WEIGHTS[2] * p[2])
                    .collect();
                Image::from_vec(self.width, self.height, 1, data)
            }
            c => Err(CoreError::InvalidImage(format!("cannot make a grey image from {c} channels"))),
        }
    }

    /// The four taps `(x0, x1, y0, y1)` and weights `(fx, fy)` of a bilinear sample at
    /// continuous coordinates `(u, v)` (pixel centres at `i + 0.5`), clamped to the border
    /// pixels outside the image: what [`Image::sample_bilinear`] interpolates, for callers that
    /// must look at the taps first (e.g. skip "no data" values).
    pub fn bilinear_taps(&self, u: f32, v: f32) -> ([usize; 4], [f32; 2]) {
        let x = (u - 0.5).clamp(0.0, (self.width - 1) as f32);
        let y = (v - 0.5).clamp(0.0, (self.height - 1) as f32);
        let x0 = x.floor() as usize;
        let y0 = y.floor() as usize;
        let x1 = (x0 + 1).min(self.width - 1);
        let y1 = (y0 + 1).min(self.height - 1);
        ([x0, x1, y0, y1], [x - x0 as f32, y - y0 as f32])
    }

    /// Bilinear sample of channel `c` at continuous coordinates `(u, v)` (pixel centres at
    /// `i + 0.5`), clamping to the border pixels outside the image.
    pub fn sample_bilinear(&self, u: f32, v: f32, c: usize) -> f32 {
        let ([x0, x1, y0, y1], [fx, fy]) = self.bilinear_taps(u, v);
        let a = self.get(x0, y0, c) * (1.0 - fx) + self.get(x1, y0, c) * fx;
        let b = self.get(x0, y1, c) * (1.0 - fx) + self.get(x1, y1, c) * fx;
        a * (1.0 - fy) + b * fy
    }

    /// Area-weighted (box-filter) resize to `width × height`: every output pixel is the exact
    /// average of the input area it covers, which is alias-free for downscaling
    /// (`-r 2|4|8` and a target width) and bilinear-like for upscaling.
    pub fn resize_area(&self, width: usize, height: usize) -> Result<Image> {
        Self::check_size(width, height, self.channels)?;
        if width == self.width && height == self.height {
            return Ok(self.clone());
        }
        let xw = area_weights(self.width, width);
        let yw = area_weights(self.height, height);
        let c = self.channels;
        // Horizontal pass into [H_in][W_out][C], then vertical.
        let mut tmp = vec![0.0f32; self.height * width * c];
        for y in 0..self.height {
            let src = self.row(y);
            let dst = &mut tmp[y * width * c..(y + 1) * width * c];
            for (ox, taps) in xw.iter().enumerate() {
                for &(ix, w) in taps {
                    for ch in 0..c {
                        dst[ox * c + ch] += w * src[ix * c + ch];
                    }
                }
            }
        }
        let mut out = vec![0.0f32; height * width * c];
        for (oy, taps) in yw.iter().enumerate() {
            let dst = &mut out[oy * width * c..(oy + 1) * width * c];
            for &(iy, w) in taps {
                let src = &tmp[iy * width * c..(iy + 1) * width * c];
                for (d, s) in dst.iter_mut().zip(src) {
                    *d += w * s;
                }
            }
        }
        Image::from_vec(width, height, c, out)
    }
}

/// For each output sample, the input samples it covers with normalised overlap weights.
fn area_weights(n_in: usize, n_out: usize) -> Vec<Vec<(usize, f32)>> {
    let scale = n_in as f64 / n_out as f64;
    (0..n_out)
        .map(|o| {
            if scale >= 1.0 {
                let lo = o as f64 * scale;
                let hi = lo + scale;
                let mut taps = Vec::new();
                let mut i = lo.floor() as usize;
                while (i as f64) < hi && i < n_in {
                    let overlap = (hi.min(i as f64 + 1.0) - lo.max(i as f64)).max(0.0);
                    if overlap > 0.0 {
                        taps.push((i, (overlap / scale) as f32));
                    }
                    i += 1;
                }
                taps
            } else {
                // Upscaling: linear interpolation between input centres.
                let centre = (o as f64 + 0.5) * scale - 0.5;
                let c = centre.clamp(0.0, (n_in - 1) as f64);
                let i0 = c.floor() as usize;
                let i1 = (i0 + 1).min(n_in - 1);
                let f = (c - i0 as f64) as f32;
                if i0 == i1 { vec![(i0, 1.0)] } else { vec![(i0, 1.0 - f), (i1, f)] }
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {

    #[test]
    fn grid_sizes_are_checked_in_one_place() {
        assert_eq!(super::grid_len_mismatch(4, 3, 2, 24), None);
        assert_eq!(super::grid_len_mismatch(4, 3, 2, 23).unwrap(), "a 4x3x2 grid needs 24 values, the buffer has 23");
        assert!(super::grid_len_mismatch(usize::MAX, 2, 1, 0).unwrap().contains("too large"));
        assert!(Image::from_vec(2, 2, 3, vec![0.0; 11]).unwrap_err().to_string().contains("needs 12 values"));
    }

    use super::*;

    #[test]
    fn layout_is_row_major_hwc() {
        let mut img = Image::new(3, 2, 3).unwrap();
        img.set(2, 1, 1, 7.0);
        assert_eq!(img.data()[(1 * 3 + 2) * 3 + 1], 7.0);
        assert_eq!(img.pixel(2, 1), &[0.0, 7.0, 0.0]);
    }

    #[test]
    fn rejects_bad_sizes() {
        assert!(Image::new(0, 3, 3).is_err());
        assert!(Image::from_vec(2, 2, 3, vec![0.0; 11]).is_err());
        assert!(Image::new(100_000, 100_000, 1).is_err());
    }

    #[test]
    fn bilinear_uses_pixel_centres() {
        let img = Image::from_vec(2, 1, 1, vec![0.0, 1.0]).unwrap();
        assert_eq!(img.sample_bilinear(0.5, 0.5, 0), 0.0);
        assert_eq!(img.sample_bilinear(1.5, 0.5, 0), 1.0);
        assert!((img.sample_bilinear(1.0, 0.5, 0) - 0.5).abs() < 1e-7);
        assert_eq!(img.sample_bilinear(-3.0, 0.5, 0), 0.0);
    }

    #[test]
    fn area_downscale_averages_blocks() {
        let img = Image::from_vec(4, 2, 1, vec![0.0, 2.0, 4.0, 6.0, 2.0, 4.0, 6.0, 8.0]).unwrap();
        let half = img.resize_area(2, 1).unwrap();
        assert_eq!(half.data(), &[2.0, 6.0]);
        // Non-integer ratio keeps the mean.
        let odd = Image::from_vec(5, 1, 1, vec![1.0, 2.0, 3.0, 4.0, 5.0]).unwrap().resize_area(2, 1).unwrap();
        let mean: f32 = odd.data().iter().sum::<f32>() / 2.0;
        assert!((mean - 3.0).abs() < 1e-6);
    }

    #[test]
    fn grey_weights() {
        let img = Image::from_vec(1, 1, 3, vec![1.0, 0.0, 0.0]).unwrap();
        assert!((img.to_grey().unwrap().get(0, 0, 0) - 0.299).abs() < 1e-7);
    }
}
