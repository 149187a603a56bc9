//! PLY point clouds, and whitespace-separated `x y z` text.
//!
//! Writing: binary little-endian, `element vertex N` with `x y z` `float` and,
//! when the cloud has colours, `red green blue` `uchar` — what Open3D,
//! CloudCompare, MeshLab and `plyfile` read. The file is written next to its
//! destination under a temporary name and renamed, so an interrupted run never
//! leaves a half file under the final name.
//!
//! Reading: `ascii`, `binary_little_endian` and `binary_big_endian`; the vertex
//! element's `x y z` of any scalar type (read into `f32`), colours from
//! `red green blue` (integer types as 0–255, floats as 0–1), or grey from an
//! `intensity` property when there is no colour. Other elements (faces, …) are
//! skipped, and bytes after the vertex data are ignored: the LSD-SLAM viewer's
//! `pc.ply` (`x y z intensity` floats) ends with one stray byte.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::Path;

use rayon::prelude::*;

use crate::cloud::PointCloud;
use crate::error::{Error, Result};
use crate::io::atomic::OutputSet;
use crate::io::spill::CloudRef;

/// Vertices per block when encoding or decoding binary data in parallel.
const VERTICES_PER_TASK: usize = 1 << 14;

/// Writes `cloud` as a binary little-endian PLY (`x y z` float, `red green blue`
/// uchar when the cloud has colours). Atomic: temp file in the same folder, then rename.
pub fn write_ply(path: impl AsRef<Path>, cloud: &PointCloud) -> Result<()> {
    write_ply_parts(path.as_ref(), &cloud.points, cloud.colors.as_deref())
}

/// [`write_ply`] from the raw buffers: `points` row-major `(N, 3)`, `colors` `(N, 3)` bytes.
pub fn write_ply_parts(path: &Path, points: &[f32], colors: Option<&[u8]>) -> Result<()> {
    let mut set = OutputSet::new();
    write_ply_into(&mut set, path, points, colors)?;
    set.commit().map(|_| ())
}

/// [`write_ply_parts`] as one output of `set` (published when the set is committed).
pub fn write_ply_into(
    set: &mut OutputSet,
    path: &Path,
    points: &[f32],
    colors: Option<&[u8]>,
) -> Result<()> {
    check_shapes(points, colors)?;
    write_ply_cloud_into(set, path, CloudRef::Memory(points, colors))
}

/// `points` `(N, 3)` and `colors` `(N, 3)` (when given) agree.
pub(crate) fn check_shapes(points: &[f32], colors: Option<&[u8]>) -> Result<()> {
    if points.len() % 3 != 0 {
        return Err(Error::ShapeMismatch {
            what: "points".into(),
            expected: "(N, 3)".into(),
            got: format!("{} values", points.len()),
        });
    }
    let n = points.len() / 3;
    if let Some(c) = colors {
        if c.len() != 3 * n {
            return Err(Error::ShapeMismatch {
                what: "colors".into(),
                expected: format!("({n}, 3)"),
                got: format!("{} values", c.len()),
            });
        }
    }
    Ok(())
}

/// [`write_ply_into`] of a cloud in memory or on disk, a piece at a time.
pub fn write_ply_cloud_into(set: &mut OutputSet, path: &Path, cloud: CloudRef<'_>) -> Result<()> {
    let n = cloud.len();
    let with_colors = cloud.has_colors();
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment slam2world point cloud\nelement vertex {n}\n\
         property float x\nproperty float y\nproperty float z\n"
    );
    if with_colors {
        header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    header.push_str("end_header\n");
    let stride = if with_colors { 15 } else { 12 };

    let io_err = |e| Error::io(path, e);
    set.write(path, |file| {
        let mut w = BufWriter::with_capacity(1 << 20, file);
        w.write_all(header.as_bytes()).map_err(io_err)?;
        // Encode blocks of vertices in parallel, a piece of blocks at a time, and
        // write them in order.
        let batch = VERTICES_PER_TASK * rayon::current_num_threads().max(1);
        let mut buf = Vec::new();
        cloud.for_each_piece(batch, |points, colors| {
            crate::interrupt::check()?;
            buf.clear();
            buf.resize(points.len() / 3 * stride, 0u8);
            buf.par_chunks_mut(VERTICES_PER_TASK * stride)
                .enumerate()
                .for_each(|(b, out)| {
                    let first = b * VERTICES_PER_TASK;
                    for (j, v) in out.chunks_exact_mut(stride).enumerate() {
                        let i = first + j;
                        for k in 0..3 {
                            v[4 * k..4 * k + 4].copy_from_slice(&points[3 * i + k].to_le_bytes());
                        }
                        if let Some(c) = colors {
                            v[12..15].copy_from_slice(&c[3 * i..3 * i + 3]);
                        }
                    }
                });
            w.write_all(&buf).map_err(io_err)
        })?;
        w.flush().map_err(io_err)
    })
}

/// Scalar types of PLY properties.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Reads one value at the start of `b` (which holds at least `size()` bytes).
    #[inline(always)]
    fn read(self, b: &[u8], big_endian: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                if big_endian {
                    <$t>::from_be_bytes(a) as f64
                } else {
                    <$t>::from_le_bytes(a) as f64
                }
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => get!(i16, 2),
            Scalar::U16 => get!(u16, 2),
            Scalar::I32 => get!(i32, 4),
            Scalar::U32 => get!(u32, 4),
            Scalar::F32 => get!(f32, 4),
            Scalar::F64 => get!(f64, 8),
        }
    }
}

/// One property of an element: a scalar, or a list (count type, item type).
#[derive(Clone, Debug)]
struct Property {
    name: String,
    kind: Scalar,
    list_count: Option<Scalar>,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

impl Element {
    /// Bytes per item when no property is a list.
    fn fixed_stride(&self) -> Option<usize> {
        self.properties
            .iter()
            .map(|p| p.list_count.is_none().then_some(p.kind.size()))
            .sum()
    }

    fn find(&self, name: &str) -> Option<usize> {
        self.properties.iter().position(|p| p.name == name)
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Format {
    Ascii,
    BinaryLe,
    BinaryBe,
}

struct Header {
    format: Format,
    elements: Vec<Element>,
    /// Byte offset of the data after `end_header`.
    data_start: usize,
    /// Lines in the header (for ASCII line numbers).
    lines: usize,
}

fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header> {
    let err = |line: usize, reason: String| Error::parse(path, line, reason);
    if !bytes.starts_with(b"ply") {
        return Err(err(1, "not a PLY file (no `ply` magic)".into()));
    }
    let mut pos = 0;
    let mut lineno = 0;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let Some(nl) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(err(lineno + 1, "header has no `end_header`".into()));
        };
        if nl > crate::io::lines::MAX_LINE_BYTES {
            return Err(err(
                lineno + 1,
                format!(
                    "header line longer than {} bytes: not a PLY header",
                    crate::io::lines::MAX_LINE_BYTES
                ),
            ));
        }
        let raw = &bytes[pos..pos + nl];
        pos += nl + 1;
        lineno += 1;
        let line = std::str::from_utf8(raw)
            .map_err(|_| err(lineno, "header line is not text".into()))?
            .trim_end_matches('\r');
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["ply"] if lineno == 1 => {}
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", f, _version] => {
                format = Some(match *f {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::BinaryLe,
                    "binary_big_endian" => Format::BinaryBe,
                    other => {
                        return Err(err(
                            lineno,
                            format!("unknown format {}", crate::error::cut(other)),
                        ))
                    }
                });
            }
            ["element", name, count] => {
                let count = count.parse::<usize>().map_err(|_| {
                    err(
                        lineno,
                        format!("bad element count {}", crate::error::cut(count)),
                    )
                })?;
                elements.push(Element {
                    name: (*name).to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["property", "list", count_t, item_t, name] => {
                let (Some(c), Some(k)) = (Scalar::parse(count_t), Scalar::parse(item_t)) else {
                    return Err(err(
                        lineno,
                        format!(
                            "unknown list types {}",
                            crate::error::cut(&format!("{count_t} {item_t}"))
                        ),
                    ));
                };
                if c.is_float() {
                    return Err(err(
                        lineno,
                        format!("list count type `{count_t}` is not an integer"),
                    ));
                }
                let Some(e) = elements.last_mut() else {
                    return Err(err(lineno, "property before any element".into()));
                };
                e.properties.push(Property {
                    name: (*name).to_string(),
                    kind: k,
                    list_count: Some(c),
                });
            }
            ["property", t, name] => {
                let Some(k) = Scalar::parse(t) else {
                    return Err(err(
                        lineno,
                        format!("unknown property type {}", crate::error::cut(t)),
                    ));
                };
                let Some(e) = elements.last_mut() else {
                    return Err(err(lineno, "property before any element".into()));
                };
                e.properties.push(Property {
                    name: (*name).to_string(),
                    kind: k,
                    list_count: None,
                });
            }
            ["end_header"] => break,
            _ => {
                return Err(err(
                    lineno,
                    format!("unexpected header line {}", crate::error::cut(line)),
                ))
            }
        }
    }
    let format = format.ok_or_else(|| err(lineno, "header has no `format` line".into()))?;
    Ok(Header {
        format,
        elements,
        data_start: pos,
        lines: lineno,
    })
}

/// Where the vertex properties we use sit, and how colours are decoded.
struct VertexLayout {
    xyz: [usize; 3],
    color: Option<ColorSource>,
}

enum ColorSource {
    Rgb([usize; 3]),
    Intensity(usize),
}

fn vertex_layout(path: &Path, e: &Element) -> Result<VertexLayout> {
    let mut xyz = [0usize; 3];
    for (k, name) in ["x", "y", "z"].iter().enumerate() {
        let i = e.find(name).ok_or_else(|| {
            Error::parse(
                path,
                0,
                format!("element `vertex` has no property `{name}`"),
            )
        })?;
        if e.properties[i].list_count.is_some() {
            return Err(Error::parse(
                path,
                0,
                format!("vertex property `{name}` is a list"),
            ));
        }
        xyz[k] = i;
    }
    let scalar = |name: &str| {
        e.find(name)
            .filter(|&i| e.properties[i].list_count.is_none())
    };
    let color = match (scalar("red"), scalar("green"), scalar("blue")) {
        (Some(r), Some(g), Some(b)) => Some(ColorSource::Rgb([r, g, b])),
        _ => scalar("intensity").map(ColorSource::Intensity),
    };
    Ok(VertexLayout { xyz, color })
}

/// A colour channel value as a byte: floats are 0–1, integers 0–255 (clamped).
#[inline]
fn to_byte(v: f64, kind: Scalar) -> u8 {
    let v = if kind.is_float() { v * 255.0 } else { v };
    if v.is_nan() {
        0
    } else {
        v.round().clamp(0.0, 255.0) as u8
    }
}

/// Reads the vertices of a PLY file (any of the three formats) as a point cloud;
/// keyframe ids are `-1`. A file that declares `element vertex 0` (what the
/// writers write when every point was dropped) reads as an empty cloud.
pub fn read_ply(path: impl AsRef<Path>) -> Result<PointCloud> {
    let path = path.as_ref();
    // A regular file is read whole (its size bounds the memory); a device or
    // FIFO could stream without end.
    let meta = fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::parse(
            path,
            0,
            "not a regular file (a folder, device or FIFO): expected a PLY file",
        ));
    }
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    let header = parse_header(path, &bytes)?;
    let Some(vi) = header.elements.iter().position(|e| e.name == "vertex") else {
        return Err(Error::parse(path, 0, "no `vertex` element"));
    };
    let layout = vertex_layout(path, &header.elements[vi])?;
    match header.format {
        Format::Ascii => read_ascii(path, &bytes, &header, vi, &layout),
        Format::BinaryLe | Format::BinaryBe => read_binary(path, &bytes, &header, vi, &layout),
    }
}

fn read_binary(
    path: &Path,
    bytes: &[u8],
    h: &Header,
    vi: usize,
    layout: &VertexLayout,
) -> Result<PointCloud> {
    let be = h.format == Format::BinaryBe;
    let truncated = |what: &str| Error::parse(path, 0, format!("data ends inside {what}"));
    let mut pos = h.data_start;
    // Skip the elements stored before the vertices.
    for e in &h.elements[..vi] {
        if let Some(stride) = e.fixed_stride() {
            let len = stride
                .checked_mul(e.count)
                .ok_or_else(|| truncated(&format!("element `{}`", e.name)))?;
            pos = pos
                .checked_add(len)
                .filter(|&p| p <= bytes.len())
                .ok_or_else(|| truncated(&format!("element `{}`", e.name)))?;
        } else {
            for _ in 0..e.count {
                for p in &e.properties {
                    let n = match p.list_count {
                        Some(c) => {
                            let b = bytes
                                .get(pos..pos + c.size())
                                .ok_or_else(|| truncated(&format!("element `{}`", e.name)))?;
                            pos += c.size();
                            c.read(b, be) as usize
                        }
                        None => 1,
                    };
                    pos = n
                        .checked_mul(p.kind.size())
                        .and_then(|l| pos.checked_add(l))
                        .filter(|&q| q <= bytes.len())
                        .ok_or_else(|| truncated(&format!("element `{}`", e.name)))?;
                }
            }
        }
    }
    let e = &h.elements[vi];
    let Some(stride) = e.fixed_stride() else {
        return Err(Error::parse(
            path,
            0,
            "element `vertex` with list properties is not supported",
        ));
    };
    let n = e.count;
    let need = stride
        .checked_mul(n)
        .filter(|&l| pos.checked_add(l).is_some_and(|end| end <= bytes.len()));
    let Some(len) = need else {
        return Err(Error::parse(
            path,
            0,
            format!(
                "{n} vertices of {stride} bytes need {} bytes of data, the file has {}",
                stride as u128 * n as u128,
                bytes.len() - pos
            ),
        ));
    };
    let data = &bytes[pos..pos + len];
    let mut offsets = Vec::with_capacity(e.properties.len());
    let mut off = 0;
    for p in &e.properties {
        offsets.push(off);
        off += p.kind.size();
    }
    let field = |i: usize| (offsets[i], e.properties[i].kind);
    let xyz = layout.xyz.map(field);
    let mut points = vec![0f32; 3 * n];
    points
        .par_chunks_mut(3 * VERTICES_PER_TASK)
        .zip(data.par_chunks(stride * VERTICES_PER_TASK))
        .for_each(|(out, src)| {
            for (o, v) in out.chunks_exact_mut(3).zip(src.chunks_exact(stride)) {
                for k in 0..3 {
                    o[k] = xyz[k].1.read(&v[xyz[k].0..], be) as f32;
                }
            }
        });
    let colors = layout.color.as_ref().map(|c| {
        let chans = match c {
            ColorSource::Rgb(rgb) => rgb.map(field),
            ColorSource::Intensity(i) => [field(*i); 3],
        };
        let mut colors = vec![0u8; 3 * n];
        colors
            .par_chunks_mut(3 * VERTICES_PER_TASK)
            .zip(data.par_chunks(stride * VERTICES_PER_TASK))
            .for_each(|(out, src)| {
                for (o, v) in out.chunks_exact_mut(3).zip(src.chunks_exact(stride)) {
                    for k in 0..3 {
                        let (off, kind) = chans[k];
                        o[k] = to_byte(kind.read(&v[off..], be), kind);
                    }
                }
            });
        colors
    });
    PointCloud::try_new(points, colors, None)
}

fn read_ascii(
    path: &Path,
    bytes: &[u8],
    h: &Header,
    vi: usize,
    layout: &VertexLayout,
) -> Result<PointCloud> {
    let text = std::str::from_utf8(&bytes[h.data_start..])
        .map_err(|_| Error::parse(path, h.lines + 1, "ASCII PLY data is not text"))?;
    // One item per non-empty line.
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (h.lines + 1 + i, l))
        .filter(|(_, l)| !l.trim().is_empty());
    for e in &h.elements[..vi] {
        for _ in 0..e.count {
            if lines.next().is_none() {
                return Err(Error::parse(
                    path,
                    0,
                    format!("data ends inside element `{}`", e.name),
                ));
            }
        }
    }
    let e = &h.elements[vi];
    let n = e.count;
    // Cap the reservation by what the file could hold (one value needs 2 bytes).
    let cap = n.min(bytes.len() / 2);
    let mut points = Vec::with_capacity(3 * cap);
    let mut colors = layout.color.as_ref().map(|_| Vec::with_capacity(3 * cap));
    let mut values = Vec::with_capacity(e.properties.len());
    for _ in 0..n {
        let Some((lineno, line)) = lines.next() else {
            return Err(Error::parse(
                path,
                0,
                format!("{n} vertices declared, fewer given"),
            ));
        };
        values.clear();
        let mut tokens = line.split_whitespace();
        let mut next = |what: &str| -> Result<f64> {
            let t = tokens
                .next()
                .ok_or_else(|| Error::parse(path, lineno, format!("missing value for `{what}`")))?;
            t.parse::<f64>().map_err(|_| {
                Error::parse(
                    path,
                    lineno,
                    format!("{} is not a number ({what})", crate::error::cut(t)),
                )
            })
        };
        for p in &e.properties {
            match p.list_count {
                None => values.push(next(&p.name)?),
                Some(_) => {
                    let c = next(&p.name)?;
                    if !(c >= 0.0 && c.fract() == 0.0) {
                        return Err(Error::parse(path, lineno, format!("bad list count `{c}`")));
                    }
                    for _ in 0..c as usize {
                        next(&p.name)?;
                    }
                    values.push(f64::NAN);
                }
            }
        }
        for &k in &layout.xyz {
            points.push(values[k] as f32);
        }
        if let (Some(out), Some(src)) = (&mut colors, &layout.color) {
            let chans = match src {
                ColorSource::Rgb(rgb) => *rgb,
                ColorSource::Intensity(i) => [*i; 3],
            };
            for c in chans {
                out.push(to_byte(values[c], e.properties[c].kind));
            }
        }
    }
    PointCloud::try_new(points, colors, None)
}

/// Reads whitespace-separated points, one `x y z` per line (further columns are
/// ignored), such as ORB-SLAM's `MapPoints.txt`. Empty lines and lines starting
/// with `#` are skipped. Keyframe ids are `-1`.
pub fn read_xyz_text(path: impl AsRef<Path>) -> Result<PointCloud> {
    let path = path.as_ref();
    let mut points = Vec::new();
    crate::io::lines::for_each_line(path, "an x y z point file", |i, line| {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            return Ok(());
        }
        let mut tokens = line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty());
        for axis in ["x", "y", "z"] {
            let t = tokens
                .next()
                .ok_or_else(|| Error::parse(path, i, format!("missing {axis} (need x y z)")))?;
            let v: f32 = t.parse().map_err(|_| {
                Error::parse(
                    path,
                    i,
                    format!("{} is not a number ({axis})", crate::error::cut(t)),
                )
            })?;
            points.push(v);
        }
        Ok(())
    })?;
    if points.is_empty() {
        return Err(Error::parse(
            path,
            0,
            "no points in the file (expected lines of x y z)",
        ));
    }
    PointCloud::try_new(points, None, None)
}

/// Reads a point cloud file: PLY (recognised by its `ply` magic line, any
/// PLY format) or whitespace-separated `x y z` text.
pub fn read_cloud(path: impl AsRef<Path>) -> Result<PointCloud> {
    use std::io::Read;
    let path = path.as_ref();
    let mut head = [0u8; 4];
    let n = std::fs::File::open(path)
        .and_then(|mut f| f.read(&mut head))
        .map_err(|e| Error::io(path, e))?;
    let is_ply = n >= 4 && &head[..3] == b"ply" && (head[3] == b'\n' || head[3] == b'\r');
    if is_ply {
        read_ply(path)
    } else {
        read_xyz_text(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cloud(n: usize, color: bool) -> PointCloud {
        let points: Vec<f32> = (0..3 * n).map(|i| (i as f32 * 0.37).sin() * 10.0).collect();
        let colors = color.then(|| (0..3 * n).map(|i| (i * 7 % 256) as u8).collect());
        PointCloud::try_new(points, colors, None).unwrap()
    }

    #[test]
    fn binary_round_trip_with_and_without_colour() {
        let dir = tempfile::tempdir().unwrap();
        for color in [false, true] {
            let c = cloud(3 * VERTICES_PER_TASK + 11, color);
            let p = dir.path().join(format!("c{color}.ply"));
            write_ply(&p, &c).unwrap();
            let back = read_ply(&p).unwrap();
            assert_eq!(back.points, c.points);
            assert_eq!(back.colors, c.colors);
            assert!(back.keyframe_ids.iter().all(|&i| i == -1));
        }
        // No temporary file left beside the outputs.
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    #[test]
    fn ascii_and_big_endian_with_other_elements() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.ply");
        fs::write(
            &p,
            "ply\r\nformat ascii 1.0\r\ncomment x\r\nelement face 1\r\nproperty list uchar int vertex_indices\r\n\
             element vertex 2\r\nproperty double x\r\nproperty double y\r\nproperty double z\r\n\
             property float red\r\nproperty float green\r\nproperty float blue\r\nend_header\r\n\
             3 0 1 1\r\n1.5 2 3 1 0 0.5\r\n-1 -2 -3e2 0 1 2\r\n",
        )
        .unwrap();
        let c = read_ply(&p).unwrap();
        assert_eq!(c.points, vec![1.5, 2.0, 3.0, -1.0, -2.0, -300.0]);
        assert_eq!(c.colors, Some(vec![255, 0, 128, 0, 255, 255]));

        let mut be = b"ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty short x\nproperty int y\nproperty double z\nend_header\n".to_vec();
        for (x, y, z) in [(1i16, -2i32, 0.25f64), (-7, 9, 1e3)] {
            be.extend_from_slice(&x.to_be_bytes());
            be.extend_from_slice(&y.to_be_bytes());
            be.extend_from_slice(&z.to_be_bytes());
        }
        fs::write(&p, &be).unwrap();
        let c = read_ply(&p).unwrap();
        assert_eq!(c.points, vec![1.0, -2.0, 0.25, -7.0, 9.0, 1000.0]);
        assert!(c.colors.is_none());
    }

    #[test]
    fn lsd_slam_viewer_pc_ply_with_stray_byte() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("pc.ply");
        let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty float intensity\nend_header\n".to_vec();
        for v in [1.0f32, 2.0, 3.0, 0.5, -1.0, -2.0, -3.0, 1.0] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.push(0xff);
        fs::write(&p, &b).unwrap();
        let c = read_ply(&p).unwrap();
        assert_eq!(c.points, vec![1.0, 2.0, 3.0, -1.0, -2.0, -3.0]);
        assert_eq!(c.colors, Some(vec![128, 128, 128, 255, 255, 255]));
    }

    #[test]
    fn malformed_files_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.ply");
        let cases: [&[u8]; 6] = [
            b"plx\n",
            b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n",
            b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n\0\0\0\0",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 nope\n",
            b"ply\nformat binary_little_endian 1.0\nelement vertex 99999999999999\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        ];
        for case in cases {
            fs::write(&p, case).unwrap();
            assert!(matches!(read_ply(&p), Err(Error::Parse { .. })), "{case:?}");
        }
        assert!(matches!(
            read_ply(dir.path().join("none.ply")),
            Err(Error::Io { .. })
        ));
        let missing_dir = dir.path().join("no/such/dir/out.ply");
        assert!(matches!(
            write_ply(missing_dir, &cloud(2, false)),
            Err(Error::Io { .. })
        ));
    }

    #[test]
    fn xyz_text() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.txt");
        fs::write(&p, "# header\n 1 2 3\n\n-4.5 5e-1 6 7\n").unwrap();
        let c = read_xyz_text(&p).unwrap();
        assert_eq!(c.points, vec![1.0, 2.0, 3.0, -4.5, 0.5, 6.0]);
        fs::write(&p, "1 2 3\n1 2\n").unwrap();
        assert!(matches!(
            read_xyz_text(&p),
            Err(Error::Parse { line: 2, .. })
        ));
    }
}
