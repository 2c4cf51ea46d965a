//! PLY files: the Inria 3DGS Gaussian layout ([`gaussian`]) and triangle meshes ([`mesh`]).
//!
//! This module holds what both share: the header parser ([`parse_header`]) and a decoder that
//! reads element data in any of the three PLY encodings (ASCII, binary little-endian, binary
//! big-endian). Writers always produce `binary_little_endian 1.0`.
//!
//! Every count in a header is checked against the bytes that follow it before anything is
//! allocated, so a small malicious file cannot request gigabytes.
//!
//! ```
//! use gs_core::{Gaussians, TriangleMesh};
//! let dir = tempfile::tempdir().unwrap();
//! // A 3DGS model, written in the Inria layout any splat viewer opens, and read back exactly.
//! let mut g = Gaussians::with_len(2).unwrap();
//! g.means[1] = [1.0, 2.0, 3.0];
//! g.sh_degree = 3;
//! let path = dir.path().join("point_cloud.ply");
//! gs_io::write_gaussian_ply(&path, &g).unwrap();
//! assert_eq!(gs_io::read_gaussian_ply(&path).unwrap(), g);
//! // A triangle mesh.
//! let mesh = TriangleMesh {
//!     positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
//!     triangles: vec![[0, 1, 2]],
//!     colors: Some(vec![[255, 0, 0]; 3]),
//! };
//! let path = dir.path().join("mesh.ply");
//! gs_io::write_mesh_ply(&path, &mesh).unwrap();
//! assert_eq!(gs_io::read_mesh_ply(&path).unwrap(), mesh);
//! ```

pub mod gaussian;
pub mod mesh;

use crate::error::{IoError, Result};
use std::path::Path;

/// How the element data after `end_header` is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyEncoding {
    /// `format ascii 1.0`: whitespace-separated decimal numbers.
    Ascii,
    /// `format binary_little_endian 1.0`.
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
}

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScalarType {
    /// `char` / `int8`.
    I8,
    /// `uchar` / `uint8`.
    U8,
    /// `short` / `int16`.
    I16,
    /// `ushort` / `uint16`.
    U16,
    /// `int` / `int32`.
    I32,
    /// `uint` / `uint32`.
    U32,
    /// `float` / `float32`.
    F32,
    /// `double` / `float64`.
    F64,
}

impl ScalarType {
    /// Size in bytes in the binary encodings.
    pub fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    /// Parses a type name (both the classic and the sized spellings).
    pub fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    /// The classic type name (`uchar`, `int`, `float`…), as the writers use.
    pub fn name(self) -> &'static str {
        match self {
            Self::I8 => "char",
            Self::U8 => "uchar",
            Self::I16 => "short",
            Self::U16 => "ushort",
            Self::I32 => "int",
            Self::U32 => "uint",
            Self::F32 => "float",
            Self::F64 => "double",
        }
    }

    /// Whether the type is an integer type.
    pub fn is_integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }
}

/// A property of an element: a scalar or a list (`property list <count> <item> <name>`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PropertyKind {
    /// One scalar value.
    Scalar(ScalarType),
    /// A count of type `count`, then that many values of type `item`.
    List {
        /// Type of the length prefix (an integer type).
        count: ScalarType,
        /// Type of each item.
        item: ScalarType,
    },
}

/// One `property` line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlyProperty {
    /// Property name (`x`, `f_dc_0`, `vertex_indices`…).
    pub name: String,
    /// Scalar or list, with its types.
    pub kind: PropertyKind,
}

/// One `element` line and its properties, in file order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlyElement {
    /// Element name (`vertex`, `face`…).
    pub name: String,
    /// Number of records.
    pub count: usize,
    /// Properties in file order.
    pub properties: Vec<PlyProperty>,
}

impl PlyElement {
    /// Index of the property called `name`.
    pub fn property_index(&self, name: &str) -> Option<usize> {
        self.properties.iter().position(|p| p.name == name)
    }

    /// Record size in bytes when every property is a scalar (binary encodings), else `None`.
    pub fn fixed_stride(&self) -> Option<usize> {
        self.properties
            .iter()
            .map(|p| match p.kind {
                PropertyKind::Scalar(t) => Some(t.size()),
                PropertyKind::List { .. } => None,
            })
            .sum()
    }

    /// The fewest bytes one record can take in `encoding` (lists counted as empty; one byte
    /// per ASCII token).
    fn min_record_bytes(&self, encoding: PlyEncoding) -> usize {
        self.properties
            .iter()
            .map(|p| match (encoding, p.kind) {
                (PlyEncoding::Ascii, _) => 1,
                (_, PropertyKind::Scalar(t)) => t.size(),
                (_, PropertyKind::List { count, .. }) => count.size(),
            })
            .sum()
    }
}

/// A parsed PLY header.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlyHeader {
    /// Data encoding.
    pub encoding: PlyEncoding,
    /// Elements in file order.
    pub elements: Vec<PlyElement>,
    /// `comment` lines (text after `comment `).
    pub comments: Vec<String>,
    /// Byte offset of the first data byte (just after the `end_header` line).
    pub data_offset: usize,
}

impl PlyHeader {
    /// The element called `name`, with its position.
    pub fn element(&self, name: &str) -> Option<(usize, &PlyElement)> {
        self.elements.iter().enumerate().find(|(_, e)| e.name == name)
    }
}

/// Reads and parses only the header of the PLY file at `path` (e.g. to list property names).
pub fn read_header(path: &Path) -> Result<PlyHeader> {
    let bytes = read_file(path)?;
    parse_header(&bytes, path)
}

/// Parses a PLY header from the start of `bytes`; `path` only names the file in errors.
///
/// Accepts `\n` or `\r\n` line ends, `comment` and `obj_info` lines, all scalar type
/// spellings; checks that each element's count can fit in the bytes after the header.
pub fn parse_header(bytes: &[u8], path: &Path) -> Result<PlyHeader> {
    if !(bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n")) {
        return Err(IoError::format(path, "not a PLY file: it does not start with the line 'ply'"));
    }
    let mut pos = 0usize;
    let mut line_no = 0usize;
    let mut encoding = None;
    let mut elements: Vec<PlyElement> = Vec::new();
    let mut comments = Vec::new();
    loop {
        line_no += 1;
        if pos >= bytes.len() {
            return Err(IoError::format(path, "PLY header has no 'end_header' line"));
        }
        let (raw, next, complete) = match bytes[pos..].iter().position(|&b| b == b'\n') {
            Some(k) => (&bytes[pos..pos + k], pos + k + 1, true),
            None => (&bytes[pos..], bytes.len(), false),
        };
        pos = next;
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        if !complete && raw != b"end_header" {
            return Err(IoError::format(path, "PLY header has no 'end_header' line (the file ends inside the header)"));
        }
        let line = std::str::from_utf8(raw)
            .map_err(|_| IoError::parse(path, line_no, "PLY header line is not valid UTF-8"))?;
        if line_no == 1 {
            continue; // "ply", checked above
        }
        let mut words = line.split_ascii_whitespace();
        let keyword = words.next().unwrap_or("");
        match keyword {
            "" => {}
            "comment" => comments.push(line.trim_start()["comment".len()..].trim().to_string()),
            "obj_info" => {}
            "format" => {
                if encoding.is_some() {
                    return Err(IoError::parse(path, line_no, "second 'format' line"));
                }
                let fmt = words.next().unwrap_or("");
                let version = words.next().unwrap_or("");
                encoding = Some(match fmt {
                    "ascii" => PlyEncoding::Ascii,
                    "binary_little_endian" => PlyEncoding::BinaryLittleEndian,
                    "binary_big_endian" => PlyEncoding::BinaryBigEndian,
                    other => {
                        return Err(IoError::parse(
                            path,
                            line_no,
                            format!("unknown PLY format '{other}' (expected ascii, binary_little_endian or binary_big_endian)"),
                        ));
                    }
                });
                if version != "1.0" {
                    return Err(IoError::parse(path, line_no, format!("unsupported PLY version '{version}' (only 1.0)")));
                }
            }
            "element" => {
                if encoding.is_none() {
                    return Err(IoError::parse(path, line_no, "'element' before the 'format' line"));
                }
                let name = words.next().ok_or_else(|| IoError::parse(path, line_no, "'element' without a name"))?;
                let count = words.next().ok_or_else(|| IoError::parse(path, line_no, "'element' without a count"))?;
                let count: usize = count
                    .parse()
                    .map_err(|_| IoError::parse(path, line_no, format!("element count '{count}' is not a non-negative integer")))?;
                elements.push(PlyElement { name: name.to_string(), count, properties: Vec::new() });
            }
            "property" => {
                let element = elements
                    .last_mut()
                    .ok_or_else(|| IoError::parse(path, line_no, "'property' before any 'element'"))?;
                let ty = |w: Option<&str>| -> Result<ScalarType> {
                    let w = w.ok_or_else(|| IoError::parse(path, line_no, "incomplete 'property' line"))?;
                    ScalarType::from_name(w).ok_or_else(|| IoError::parse(path, line_no, format!("unknown property type '{w}'")))
                };
                let first = words.next();
                let kind = if first == Some("list") {
                    let count = ty(words.next())?;
                    let item = ty(words.next())?;
                    if !count.is_integer() {
                        return Err(IoError::parse(path, line_no, "list count type must be an integer type"));
                    }
                    PropertyKind::List { count, item }
                } else {
                    PropertyKind::Scalar(ty(first)?)
                };
                let name = words.next().ok_or_else(|| IoError::parse(path, line_no, "'property' without a name"))?;
                if element.properties.iter().any(|p| p.name == name) {
                    return Err(IoError::parse(path, line_no, format!("duplicate property '{name}' in element '{}'", element.name)));
                }
                element.properties.push(PlyProperty { name: name.to_string(), kind });
            }
            "end_header" => break,
            other => return Err(IoError::parse(path, line_no, format!("unknown PLY header keyword '{other}'"))),
        }
    }
    let encoding = encoding.ok_or_else(|| IoError::format(path, "PLY header has no 'format' line"))?;
    let header = PlyHeader { encoding, elements, comments, data_offset: pos };
    check_counts(&header, bytes.len() - pos, path)?;
    Ok(header)
}

/// Rejects headers whose element counts cannot fit in `data_len` bytes (before allocating).
fn check_counts(header: &PlyHeader, data_len: usize, path: &Path) -> Result<()> {
    let mut left = data_len as u64;
    for e in &header.elements {
        let min = e.min_record_bytes(header.encoding) as u64;
        crate::capped::PLY.check_declared(path, &format!("element '{}'", e.name), (e.count as u64, "records"), min, left)?;
        left -= e.count as u64 * min;
    }
    Ok(())
}

/// Sequential decoder of element data in any encoding. Errors are plain messages; callers
/// add the file, element and record.
pub(crate) struct DataReader<'a> {
    bytes: &'a [u8],
    pos: usize,
    encoding: PlyEncoding,
}

impl<'a> DataReader<'a> {
    /// A reader positioned at the header's data offset.
    pub(crate) fn new(bytes: &'a [u8], header: &PlyHeader) -> Self {
        Self { bytes, pos: header.data_offset, encoding: header.encoding }
    }

    /// Current byte offset.
    pub(crate) fn position(&self) -> usize {
        self.pos
    }

    fn take(&mut self, n: usize) -> std::result::Result<&'a [u8], String> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
        match end {
            Some(end) => {
                let s = &self.bytes[self.pos..end];
                self.pos = end;
                Ok(s)
            }
            None => Err(format!("truncated data: the file ends at byte {}", self.bytes.len())),
        }
    }

    fn token(&mut self) -> std::result::Result<&'a str, String> {
        let b = self.bytes;
        while self.pos < b.len() && b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < b.len() && !b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if start == self.pos {
            return Err(format!("truncated data: the file ends at byte {}", b.len()));
        }
        std::str::from_utf8(&b[start..self.pos]).map_err(|_| format!("non-UTF-8 text at byte {start}"))
    }

    /// Reads one value as f64 (exact for every PLY type).
    pub(crate) fn read_f64(&mut self, ty: ScalarType) -> std::result::Result<f64, String> {
        match self.encoding {
            PlyEncoding::Ascii => {
                let t = self.token()?;
                let bad = || format!("'{t}' is not a valid {} value", ty.name());
                match ty {
                    ScalarType::F32 => t.parse::<f32>().map(f64::from).map_err(|_| bad()),
                    ScalarType::F64 => t.parse::<f64>().map_err(|_| bad()),
                    _ => {
                        let v: i64 = t.parse().map_err(|_| bad())?;
                        let (lo, hi) = match ty {
                            ScalarType::I8 => (i8::MIN as i64, i8::MAX as i64),
                            ScalarType::U8 => (0, u8::MAX as i64),
                            ScalarType::I16 => (i16::MIN as i64, i16::MAX as i64),
                            ScalarType::U16 => (0, u16::MAX as i64),
                            ScalarType::I32 => (i32::MIN as i64, i32::MAX as i64),
                            _ => (0, u32::MAX as i64),
                        };
                        if v < lo || v > hi {
                            return Err(format!("{v} is out of range for type {}", ty.name()));
                        }
                        Ok(v as f64)
                    }
                }
            }
            enc => {
                let b = self.take(ty.size())?;
                Ok(decode_binary(b, ty, enc == PlyEncoding::BinaryBigEndian))
            }
        }
    }

    /// Reads one value as f32 (exact for `float`; rounded for `double` and wide integers).
    pub(crate) fn read_f32(&mut self, ty: ScalarType) -> std::result::Result<f32, String> {
        if ty == ScalarType::F32 && self.encoding == PlyEncoding::BinaryLittleEndian {
            let b = self.take(4)?;
            return Ok(f32::from_le_bytes([b[0], b[1], b[2], b[3]]));
        }
        self.read_f64(ty).map(|v| v as f32)
    }

    /// Reads an integer (list counts and indices); floats are rejected.
    pub(crate) fn read_int(&mut self, ty: ScalarType) -> std::result::Result<i64, String> {
        if !ty.is_integer() {
            return Err(format!("expected an integer type, found {}", ty.name()));
        }
        self.read_f64(ty).map(|v| v as i64)
    }

    /// Skips one property value (a scalar or a whole list).
    pub(crate) fn skip(&mut self, kind: PropertyKind) -> std::result::Result<(), String> {
        match kind {
            PropertyKind::Scalar(t) => match self.encoding {
                PlyEncoding::Ascii => self.token().map(|_| ()),
                _ => self.take(t.size()).map(|_| ()),
            },
            PropertyKind::List { count, item } => {
                let n = self.read_int(count)?;
                if n < 0 {
                    return Err(format!("negative list length {n}"));
                }
                let n = n as usize;
                match self.encoding {
                    PlyEncoding::Ascii => {
                        for _ in 0..n {
                            self.token()?;
                        }
                        Ok(())
                    }
                    _ => {
                        let bytes = n.checked_mul(item.size()).ok_or_else(|| format!("list length {n} overflows"))?;
                        self.take(bytes).map(|_| ())
                    }
                }
            }
        }
    }

    /// Skips every record of `element`.
    pub(crate) fn skip_element(&mut self, element: &PlyElement) -> std::result::Result<(), String> {
        if self.encoding != PlyEncoding::Ascii
            && let Some(stride) = element.fixed_stride()
        {
            let n = element.count.checked_mul(stride).ok_or("element size overflows")?;
            return self.take(n).map(|_| ());
        }
        if element.properties.is_empty() {
            return Ok(());
        }
        for i in 0..element.count {
            for p in &element.properties {
                self.skip(p.kind).map_err(|m| format!("{} {i}, property '{}': {m}", element.name, p.name))?;
            }
        }
        Ok(())
    }
}

/// Decodes one binary scalar (`b.len() == ty.size()`) as f64.
#[inline]
pub(crate) fn decode_binary(b: &[u8], ty: ScalarType, big_endian: bool) -> f64 {
    macro_rules! num {
        ($t:ty, $n:literal) => {{
            let mut a = [0u8; $n];
            a.copy_from_slice(&b[..$n]);
            (if big_endian { <$t>::from_be_bytes(a) } else { <$t>::from_le_bytes(a) }) as f64
        }};
    }
    match ty {
        ScalarType::I8 => b[0] as i8 as f64,
        ScalarType::U8 => b[0] as f64,
        ScalarType::I16 => num!(i16, 2),
        ScalarType::U16 => num!(u16, 2),
        ScalarType::I32 => num!(i32, 4),
        ScalarType::U32 => num!(u32, 4),
        ScalarType::F32 => num!(f32, 4),
        ScalarType::F64 => num!(f64, 8),
    }
}

/// Reads a whole PLY file into memory under the PLY cap ([`crate::capped::PLY`]).
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>> {
    crate::capped::PLY.read(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("t.ply")
    }

    #[test]
    fn header_parses_types_lists_and_comments() {
        let text = b"ply\r\nformat ascii 1.0\r\ncomment hello world\r\nelement vertex 2\r\nproperty float32 x\r\nproperty uint8 red\r\nelement face 1\r\nproperty list uchar uint vertex_index\r\nend_header\r\n0 1\n2 3\n3 0 1 1\n";
        let h = parse_header(text, p()).unwrap();
        assert_eq!(h.encoding, PlyEncoding::Ascii);
        assert_eq!(h.comments, vec!["hello world".to_string()]);
        assert_eq!(h.elements.len(), 2);
        assert_eq!(h.elements[0].properties[0].kind, PropertyKind::Scalar(ScalarType::F32));
        assert_eq!(h.elements[0].properties[1].kind, PropertyKind::Scalar(ScalarType::U8));
        assert_eq!(h.elements[1].properties[0].kind, PropertyKind::List { count: ScalarType::U8, item: ScalarType::U32 });
        assert_eq!(&text[h.data_offset..h.data_offset + 3], b"0 1");
    }

    #[test]
    fn header_errors_are_specific() {
        let cases: &[(&[u8], &str)] = &[
            (b"plx\nformat ascii 1.0\nend_header\n", "does not start with the line 'ply'"),
            (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", "no 'end_header'"),
            (b"ply\nformat weird 1.0\nend_header\n", "unknown PLY format 'weird'"),
            (b"ply\nformat ascii 2.0\nend_header\n", "unsupported PLY version"),
            (b"ply\nformat ascii 1.0\nproperty float x\nend_header\n", "before any 'element'"),
            (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty half x\nend_header\n1\n", "unknown property type 'half'"),
            (b"ply\nformat ascii 1.0\nelement vertex -1\nend_header\n", "not a non-negative integer"),
            (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float x\nend_header\n1 1\n", "duplicate property"),
            (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty list float int x\nend_header\n1 1\n", "integer type"),
            (b"ply\nformat ascii 1.0\nbogus\nend_header\n", "unknown PLY header keyword 'bogus'"),
            (b"ply\nelement vertex 1\nend_header\n", "before the 'format' line"),
            (b"ply\nend_header\n", "no 'format' line"),
            (b"ply\nformat binary_little_endian 1.0\nelement vertex 99999999999999\nproperty float x\nend_header\n", "element 'vertex' declares 99999999999999 records of at least 4 bytes each"),
            (b"ply\nformat ascii 1.0\ncomment \xff\xfe\nend_header\n", "not valid UTF-8"),
        ];
        for (bytes, expect) in cases {
            let e = parse_header(bytes, p()).unwrap_err().to_string();
            assert!(e.contains(expect) && e.contains("t.ply"), "{e:?} lacks {expect:?}");
        }
    }

    #[test]
    fn reader_decodes_all_encodings() {
        let be = b"ply\nformat binary_big_endian 1.0\nelement v 1\nproperty short a\nproperty double b\nend_header\n";
        let mut bytes = be.to_vec();
        bytes.extend_from_slice(&(-3i16).to_be_bytes());
        bytes.extend_from_slice(&1.5f64.to_be_bytes());
        let h = parse_header(&bytes, p()).unwrap();
        let mut r = DataReader::new(&bytes, &h);
        assert_eq!(r.read_int(ScalarType::I16).unwrap(), -3);
        assert_eq!(r.read_f32(ScalarType::F64).unwrap(), 1.5);
        assert!(r.read_f32(ScalarType::F32).unwrap_err().contains("truncated"));

        let asc = b"ply\nformat ascii 1.0\nelement v 1\nproperty uchar a\nend_header\n256 -1 x";
        let h = parse_header(asc, p()).unwrap();
        let mut r = DataReader::new(asc, &h);
        assert!(r.read_int(ScalarType::U8).unwrap_err().contains("out of range"));
        assert!(r.read_int(ScalarType::U8).unwrap_err().contains("out of range"));
        assert!(r.read_f32(ScalarType::F32).unwrap_err().contains("not a valid float"));
    }
}
