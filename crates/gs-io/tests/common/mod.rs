//! Helpers shared by gs-io's integration tests.

/// A NumPy v1.0 file: the header dictionary with `descr`, `fortran_order` and `shape` as
/// written (padded to 64 bytes as NumPy does), then `data_len` zero bytes. Any shape can be
/// declared, including ones the data cannot hold.
pub fn npy(descr: &str, fortran: &str, shape: &str, data_len: usize) -> Vec<u8> {
    let mut h = format!("{{'descr': '{descr}', 'fortran_order': {fortran}, 'shape': {shape}, }}");
    while (h.len() + 11) % 64 != 0 {
        h.push(' ');
    }
    h.push('\n');
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend_from_slice(&(h.len() as u16).to_le_bytes());
    b.extend_from_slice(h.as_bytes());
    b.extend(std::iter::repeat_n(0u8, data_len));
    b
}
