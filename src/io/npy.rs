//! NumPy `.npy` arrays (format versions 1.0, 2.0 and 3.0), read into flat
//! row-major vectors.
//!
//! Only what `numpy.save` writes for plain numeric arrays is accepted: dtypes
//! `u1`/`i1`/`f4`/`f8` (either byte order), C order. Every length is checked
//! against the bytes of the file before anything is allocated: the header
//! length against the bytes left, the product of the shape (with overflow
//! checks) times the item size against the data that follows, exactly.
//!
//! Written here rather than taken from `npyz` / `ndarray-npy`: both allocate a
//! buffer of the header length the file declares (up to 4 GiB for version 2)
//! before reading it, and `npyz` multiplies the shape unchecked (a panic in
//! debug builds on a hostile shape); both parse the header with a general
//! Python-literal parser the three fixed keys do not need.

use std::path::Path;

use crate::error::{Error, Result};

const MAGIC: &[u8; 6] = b"\x93NUMPY";

/// Element type of an array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NpyDtype {
    /// `|u1`: unsigned bytes (images).
    U8,
    /// `|i1`: signed bytes.
    I8,
    /// `f4`: 32-bit floats.
    F32,
    /// `f8`: 64-bit floats.
    F64,
}

impl NpyDtype {
    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            NpyDtype::U8 | NpyDtype::I8 => 1,
            NpyDtype::F32 => 4,
            NpyDtype::F64 => 8,
        }
    }
}

/// The elements of an array, in its own type.
#[derive(Clone, Debug, PartialEq)]
pub enum NpyData {
    /// `u1` elements.
    U8(Vec<u8>),
    /// `i1` elements.
    I8(Vec<i8>),
    /// `f4` elements (converted to native byte order).
    F32(Vec<f32>),
    /// `f8` elements (converted to native byte order).
    F64(Vec<f64>),
}

/// One array: its shape and its elements in C (row-major) order.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray {
    /// Dimensions, outermost first (`()` for a scalar).
    pub shape: Vec<usize>,
    /// `shape.iter().product()` elements.
    pub data: NpyData,
}

impl NpyArray {
    /// The element type.
    pub fn dtype(&self) -> NpyDtype {
        match self.data {
            NpyData::U8(_) => NpyDtype::U8,
            NpyData::I8(_) => NpyDtype::I8,
            NpyData::F32(_) => NpyDtype::F32,
            NpyData::F64(_) => NpyDtype::F64,
        }
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        match &self.data {
            NpyData::U8(v) => v.len(),
            NpyData::I8(v) => v.len(),
            NpyData::F32(v) => v.len(),
            NpyData::F64(v) => v.len(),
        }
    }

    /// True for an array with no elements.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The elements as `f64` (floats and bytes widen exactly).
    pub fn to_f64(&self) -> Vec<f64> {
        match &self.data {
            NpyData::U8(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::I8(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::F32(v) => v.iter().map(|&x| x as f64).collect(),
            NpyData::F64(v) => v.clone(),
        }
    }

    /// The elements as `f32` (`f8` values are rounded to the nearest `f32`).
    pub fn to_f32(&self) -> Vec<f32> {
        match &self.data {
            NpyData::U8(v) => v.iter().map(|&x| x as f32).collect(),
            NpyData::I8(v) => v.iter().map(|&x| x as f32).collect(),
            NpyData::F32(v) => v.clone(),
            NpyData::F64(v) => v.iter().map(|&x| x as f32).collect(),
        }
    }
}

/// Reads a `.npy` file.
pub fn read_npy(path: &Path) -> Result<NpyArray> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::BinaryFormat {
            path: path.into(),
            offset: 0,
            what: "file".into(),
            expected: "a regular file".into(),
            found: "a device, folder or other special file".into(),
        });
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse_npy(path, &bytes)
}

fn bad(
    path: &Path,
    offset: usize,
    what: &str,
    expected: impl Into<String>,
    found: impl Into<String>,
) -> Error {
    Error::BinaryFormat {
        path: path.into(),
        offset: offset as u64,
        what: what.into(),
        expected: expected.into(),
        found: found.into(),
    }
}

/// Parses the bytes of a `.npy` file (`path` names it in errors).
pub fn parse_npy(path: &Path, bytes: &[u8]) -> Result<NpyArray> {
    if bytes.len() < 10 || &bytes[..6] != MAGIC {
        let n = bytes.len().min(6);
        return Err(bad(
            path,
            0,
            "magic",
            "\\x93NUMPY",
            format!("{:?}", String::from_utf8_lossy(&bytes[..n])),
        ));
    }
    let (major, minor) = (bytes[6], bytes[7]);
    let (header_len, header_start) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err(bad(
                    path,
                    8,
                    "header length",
                    "4 bytes",
                    format!("{} bytes", bytes.len() - 8),
                ));
            }
            (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
                12,
            )
        }
        _ => {
            return Err(bad(
                path,
                6,
                "version",
                "1.0, 2.0 or 3.0",
                format!("{major}.{minor}"),
            ));
        }
    };
    let left = bytes.len() - header_start;
    if header_len > left {
        return Err(bad(
            path,
            header_start - if major == 1 { 2 } else { 4 },
            "header length",
            format!("at most the {left} bytes left"),
            header_len.to_string(),
        ));
    }
    let raw = &bytes[header_start..header_start + header_len];
    let text = std::str::from_utf8(raw)
        .ok()
        .filter(|t| major == 3 || t.is_ascii())
        .ok_or_else(|| {
            bad(
                path,
                header_start,
                "header",
                "ASCII text (UTF-8 for version 3)",
                "other bytes",
            )
        })?;
    let header = parse_header(text).map_err(|reason| {
        bad(
            path,
            header_start,
            "header",
            reason,
            format!("{:?}", text.trim_end()),
        )
    })?;
    let data_start = header_start + header_len;
    let count = header
        .shape
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .ok_or_else(|| {
            bad(
                path,
                header_start,
                "shape",
                "a size that fits in memory",
                format!("{:?}", header.shape),
            )
        })?;
    let need = count.checked_mul(header.dtype.size()).ok_or_else(|| {
        bad(
            path,
            header_start,
            "shape",
            "a size that fits in memory",
            format!("{:?}", header.shape),
        )
    })?;
    let data = &bytes[data_start..];
    if data.len() != need {
        return Err(bad(
            path,
            data_start,
            "data",
            format!(
                "{need} bytes for shape {:?} of {}",
                header.shape, header.descr
            ),
            format!("{} bytes", data.len()),
        ));
    }
    let le = header.little_endian;
    let data = match header.dtype {
        NpyDtype::U8 => NpyData::U8(data.to_vec()),
        NpyDtype::I8 => NpyData::I8(data.iter().map(|&b| b as i8).collect()),
        NpyDtype::F32 => NpyData::F32(
            data.chunks_exact(4)
                .map(|c| {
                    let b = [c[0], c[1], c[2], c[3]];
                    if le {
                        f32::from_le_bytes(b)
                    } else {
                        f32::from_be_bytes(b)
                    }
                })
                .collect(),
        ),
        NpyDtype::F64 => NpyData::F64(
            data.chunks_exact(8)
                .map(|c| {
                    let b = [c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]];
                    if le {
                        f64::from_le_bytes(b)
                    } else {
                        f64::from_be_bytes(b)
                    }
                })
                .collect(),
        ),
    };
    Ok(NpyArray {
        shape: header.shape,
        data,
    })
}

struct Header {
    descr: String,
    dtype: NpyDtype,
    little_endian: bool,
    shape: Vec<usize>,
}

/// A value of the header dictionary.
enum Value {
    Str(String),
    Bool(bool),
    Tuple(Vec<usize>),
}

/// Parses `{'descr': '<f4', 'fortran_order': False, 'shape': (3, 4), }`.
fn parse_header(text: &str) -> std::result::Result<Header, String> {
    let mut p = Lexer {
        s: text.trim_end_matches(['\n', ' ', '\0']).as_bytes(),
        i: 0,
    };
    let mut descr = None;
    let mut fortran = None;
    let mut shape = None;
    p.expect(b'{')?;
    loop {
        p.skip_ws();
        if p.eat(b'}') {
            break;
        }
        let key = p.string()?;
        p.expect(b':')?;
        let value = p.value()?;
        match (key.as_str(), value) {
            ("descr", Value::Str(s)) => descr = Some(s),
            ("fortran_order", Value::Bool(b)) => fortran = Some(b),
            ("shape", Value::Tuple(t)) => shape = Some(t),
            (k, _) => return Err(format!("the keys descr (a string), fortran_order (a bool), shape (a tuple); got {k:?} or a value of another type")),
        }
        p.skip_ws();
        if !p.eat(b',') {
            p.expect(b'}')?;
            break;
        }
    }
    p.skip_ws();
    if p.i != p.s.len() {
        return Err("nothing after the closing brace".into());
    }
    let descr = descr.ok_or("a 'descr' key")?;
    let shape = shape.ok_or("a 'shape' key")?;
    if fortran.ok_or("a 'fortran_order' key")? {
        return Err("fortran_order False (C order)".into());
    }
    let (order, ty) = descr.split_at(descr.len().min(1));
    let little_endian = match order {
        "<" | "|" => true,
        "=" => cfg!(target_endian = "little"),
        ">" => false,
        _ => return Err(format!("a dtype u1, i1, f4 or f8, got {descr:?}")),
    };
    let dtype = match ty {
        "u1" => NpyDtype::U8,
        "i1" => NpyDtype::I8,
        "f4" => NpyDtype::F32,
        "f8" => NpyDtype::F64,
        _ => return Err(format!("a dtype u1, i1, f4 or f8, got {descr:?}")),
    };
    Ok(Header {
        descr,
        dtype,
        little_endian,
        shape,
    })
}

struct Lexer<'a> {
    s: &'a [u8],
    i: usize,
}

impl Lexer<'_> {
    fn skip_ws(&mut self) {
        while self.i < self.s.len() && self.s[self.i].is_ascii_whitespace() {
            self.i += 1;
        }
    }

    fn eat(&mut self, c: u8) -> bool {
        self.skip_ws();
        if self.s.get(self.i) == Some(&c) {
            self.i += 1;
            true
        } else {
            false
        }
    }

    fn expect(&mut self, c: u8) -> std::result::Result<(), String> {
        if self.eat(c) {
            Ok(())
        } else {
            Err(format!(
                "a Python dict literal ({:?} at character {})",
                c as char, self.i
            ))
        }
    }

    fn string(&mut self) -> std::result::Result<String, String> {
        self.skip_ws();
        let q = match self.s.get(self.i) {
            Some(&q @ (b'\'' | b'"')) => q,
            _ => return Err(format!("a quoted string at character {}", self.i)),
        };
        let start = self.i + 1;
        let end = self.s[start..]
            .iter()
            .position(|&c| c == q)
            .map(|k| start + k)
            .ok_or("a closing quote")?;
        self.i = end + 1;
        Ok(String::from_utf8_lossy(&self.s[start..end]).into_owned())
    }

    fn value(&mut self) -> std::result::Result<Value, String> {
        self.skip_ws();
        match self.s.get(self.i) {
            Some(b'\'' | b'"') => Ok(Value::Str(self.string()?)),
            Some(b'(') => {
                self.i += 1;
                let mut dims = Vec::new();
                loop {
                    if self.eat(b')') {
                        break;
                    }
                    self.skip_ws();
                    let start = self.i;
                    while self.i < self.s.len() && self.s[self.i].is_ascii_digit() {
                        self.i += 1;
                    }
                    let digits = std::str::from_utf8(&self.s[start..self.i]).unwrap_or("");
                    let d: usize = digits
                        .parse()
                        .map_err(|_| format!("a non-negative dimension at character {start}"))?;
                    dims.push(d);
                    if !self.eat(b',') {
                        self.expect(b')')?;
                        break;
                    }
                }
                Ok(Value::Tuple(dims))
            }
            _ => {
                let rest = &self.s[self.i..];
                for (word, v) in [(&b"True"[..], true), (&b"False"[..], false)] {
                    if rest.starts_with(word) {
                        self.i += word.len();
                        return Ok(Value::Bool(v));
                    }
                }
                Err(format!(
                    "a string, a bool or a tuple at character {}",
                    self.i
                ))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(header: &str, data: &[u8]) -> Vec<u8> {
        let mut h = header.to_string();
        while (10 + h.len() + 1) % 64 != 0 {
            h.push(' ');
        }
        h.push('\n');
        let mut v = MAGIC.to_vec();
        v.extend([1, 0]);
        v.extend((h.len() as u16).to_le_bytes());
        v.extend(h.as_bytes());
        v.extend(data);
        v
    }

    #[test]
    fn reads_f4_and_u1_arrays() {
        let data: Vec<u8> = [1.5f32, -2.0, 3.25, 0.0, 7.0, 8.5]
            .iter()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let a = parse_npy(
            Path::new("a.npy"),
            &file(
                "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }",
                &data,
            ),
        )
        .unwrap();
        assert_eq!(a.shape, vec![2, 3]);
        assert_eq!(a.data, NpyData::F32(vec![1.5, -2.0, 3.25, 0.0, 7.0, 8.5]));
        let b = parse_npy(
            Path::new("b.npy"),
            &file(
                "{'descr': '|u1', 'fortran_order': False, 'shape': (4,), }",
                &[1, 2, 3, 4],
            ),
        )
        .unwrap();
        assert_eq!(b.data, NpyData::U8(vec![1, 2, 3, 4]));
        let be: Vec<u8> = 2.5f64.to_be_bytes().to_vec();
        let c = parse_npy(
            Path::new("c.npy"),
            &file(
                "{'descr': '>f8', 'fortran_order': False, 'shape': (), }",
                &be,
            ),
        )
        .unwrap();
        assert_eq!((c.shape.len(), c.to_f64()), (0, vec![2.5]));
    }

    #[test]
    fn every_truncation_is_an_error() {
        let data: Vec<u8> = (0..24).collect();
        let good = file(
            "{'descr': '<f8', 'fortran_order': False, 'shape': (3,), }",
            &data,
        );
        assert!(parse_npy(Path::new("t.npy"), &good).is_ok());
        for cut in 0..good.len() {
            assert!(
                parse_npy(Path::new("t.npy"), &good[..cut]).is_err(),
                "cut at {cut}"
            );
        }
    }

    #[test]
    fn refuses_lying_shapes_dtypes_and_headers() {
        let p = Path::new("x.npy");
        let cases: Vec<(Vec<u8>, &str)> = vec![
            (
                file(
                    "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }",
                    &[0; 20],
                ),
                "data",
            ),
            (
                file(
                    "{'descr': '<f4', 'fortran_order': False, 'shape': (4294967296, 4294967296), }",
                    &[],
                ),
                "shape",
            ),
            (
                file(
                    "{'descr': '<c16', 'fortran_order': False, 'shape': (1,), }",
                    &[0; 16],
                ),
                "header",
            ),
            (
                file(
                    "{'descr': '<f4', 'fortran_order': True, 'shape': (1,), }",
                    &[0; 4],
                ),
                "header",
            ),
            (file("{'descr': '<f4', 'shape': (1,), }", &[0; 4]), "header"),
            (
                file(
                    "{'descr': '<f4', 'fortran_order': False, 'shape': (-1,), }",
                    &[0; 4],
                ),
                "header",
            ),
            (b"\x93NUMPX\x01\x00\x00\x00".to_vec(), "magic"),
            (b"\x93NUMPY\x01\x00\xff\xff{}".to_vec(), "header length"),
            (
                b"\x93NUMPY\x02\x00\xff\xff\xff\xff{}".to_vec(),
                "header length",
            ),
            (b"\x93NUMPY\x09\x00\x00\x00".to_vec(), "version"),
        ];
        for (bytes, field) in cases {
            match parse_npy(p, &bytes) {
                Err(Error::BinaryFormat { what, .. }) => assert_eq!(what, field),
                other => panic!("{field}: {other:?}"),
            }
        }
    }
}
