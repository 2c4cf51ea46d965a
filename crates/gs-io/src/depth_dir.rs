//! Per-view depth maps kept beside a scene (`vagsl mesh --depth-dir`, `vagsl eval-images
//! --seen-from`): a folder with one camera-z map per view, named after the view's image.

use crate::error::{IoError, Result};
use gs_core::Image;
use std::path::Path;

/// The file names tried for view `name` (an image file name such as `0003.png`), in order:
/// `STEM.exr`, `STEM_depth.exr` (what `vagsl render` writes), `depth_STEM.npy` (the synthetic
/// scenes' `gt/` folders) and `STEM.npy`.
pub fn depth_candidates(name: &str) -> [String; 4] {
    let stem = Path::new(name).file_stem().map_or(name.to_string(), |s| s.to_string_lossy().into_owned());
    [format!("{stem}.exr"), format!("{stem}_depth.exr"), format!("depth_{stem}.npy"), format!("{stem}.npy")]
}

/// The one-channel depth map of view `name` in `dir`: the first of [`depth_candidates`] that
/// exists. An error names the folder and the files looked for when none does, and the file
/// when it is not a one-channel map.
pub fn read_view_depth(dir: &Path, name: &str) -> Result<Image> {
    let names = depth_candidates(name);
    for cand in &names {
        let p = dir.join(cand);
        if p.is_file() {
            let img = if cand.ends_with(".exr") { crate::read_exr(&p)? } else { crate::read_npy(&p)? };
            if img.channels() != 1 {
                return Err(IoError::Format {
                    path: p,
                    message: format!("a depth map has 1 channel, this one has {}", img.channels()),
                });
            }
            return Ok(img);
        }
    }
    Err(IoError::Invalid { path: dir.to_path_buf(), message: format!("no depth map for view '{name}' (looked for {})", names.join(", ")) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_each_naming_and_names_what_is_missing() {
        let dir = std::env::temp_dir().join(format!("gs-io-depth-dir-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let depth = Image::from_vec(2, 1, 1, vec![1.5, 2.0]).unwrap();
        crate::write_npy(&dir.join("depth_0003.npy"), &depth).unwrap();
        assert_eq!(read_view_depth(&dir, "0003.png").unwrap().data(), depth.data());
        let e = read_view_depth(&dir, "0004.png").unwrap_err().to_string();
        assert!(e.contains("no depth map for view '0004.png'") && e.contains("depth_0004.npy"), "{e}");
        let rgb = Image::from_vec(1, 1, 3, vec![0.0; 3]).unwrap();
        crate::write_npy(&dir.join("0005.npy"), &rgb).unwrap();
        let e = read_view_depth(&dir, "0005.jpg").unwrap_err().to_string();
        assert!(e.contains("0005.npy") && e.contains("1 channel, this one has 3"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
