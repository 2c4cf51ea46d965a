//! The input layout of the COLMAP targets: `u16 LE length of the cameras file, u16 LE length
//! of the images file`, then the three files back to back (lengths clamped to the bytes
//! available; the points file is the rest).

/// The cameras, images and points parts of `data`; `None` below the 4-byte header.
pub fn split(data: &[u8]) -> Option<(&[u8], &[u8], &[u8])> {
    if data.len() < 4 {
        return None;
    }
    let (head, rest) = data.split_at(4);
    let a = (u16::from_le_bytes([head[0], head[1]]) as usize).min(rest.len());
    let (cams, tail) = rest.split_at(a);
    let b = (u16::from_le_bytes([head[2], head[3]]) as usize).min(tail.len());
    let (imgs, pts) = tail.split_at(b);
    Some((cams, imgs, pts))
}
