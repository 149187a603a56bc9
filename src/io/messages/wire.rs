//! Byte-level readers and writers for the three binary message encodings the
//! logs use: ROS 1 (packed little-endian), ROS 2 CDR (XCDR1, aligned, either
//! byte order) and the protobuf wire format. Every read is bounds-checked and
//! returns a [`WireError`] saying what was short or malformed and where; the
//! log readers add the file, topic and message index
//! ([`crate::Error::Decode`]).

pub use crate::error::WireError;

/// The result of a wire read.
pub type WireResult<T> = std::result::Result<T, WireError>;

/// The bytes of one message and the read position: what the ROS 1 and the
/// CDR reader share.
#[derive(Clone, Copy, Debug)]
struct Cursor<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    /// The next `n` bytes, or where the message was short.
    #[inline]
    fn bytes(&mut self, n: usize) -> WireResult<&'a [u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.buf.len());
        match end {
            Some(end) => {
                let s = &self.buf[self.pos..end];
                self.pos = end;
                Ok(s)
            }
            None => Err(WireError::Truncated {
                offset: self.pos,
                need: n,
                len: self.buf.len(),
            }),
        }
    }

    #[inline]
    fn array<const N: usize>(&mut self) -> WireResult<[u8; N]> {
        let b = self.bytes(N)?;
        let mut a = [0u8; N];
        a.copy_from_slice(b);
        Ok(a)
    }
}

/// The reads of a ROS message encoding (ROS 1 or CDR): each encoding says how a
/// primitive of `N` bytes is found ([`RosReader::primitive`]: its alignment,
/// its byte order), how a string and a `std_msgs/Header` are laid out; the
/// typed reads are the same for both.
pub trait RosReader<'a> {
    /// The next primitive of `N` bytes, aligned as the encoding asks, in
    /// little-endian order.
    fn primitive<const N: usize>(&mut self) -> WireResult<[u8; N]>;

    /// The next `n` raw bytes (no alignment).
    fn bytes(&mut self, n: usize) -> WireResult<&'a [u8]>;

    /// `string`.
    fn string(&mut self) -> WireResult<String>;

    /// `std_msgs/Header`: (stamp seconds, frame_id).
    fn header(&mut self) -> WireResult<(f64, String)>;

    /// The stamp of a `std_msgs/Header`, its frame skipped (no allocation).
    fn header_stamp(&mut self) -> WireResult<f64>;

    /// The length of an array or sequence (`T[]`, `sequence<T>`).
    fn seq_len(&mut self) -> WireResult<usize> {
        Ok(self.u32()? as usize)
    }

    /// `uint8` / `int8` / `bool`.
    fn u8(&mut self) -> WireResult<u8> {
        Ok(self.primitive::<1>()?[0])
    }
    /// `uint16`.
    fn u16(&mut self) -> WireResult<u16> {
        Ok(u16::from_le_bytes(self.primitive()?))
    }
    /// `uint32`.
    fn u32(&mut self) -> WireResult<u32> {
        Ok(u32::from_le_bytes(self.primitive()?))
    }
    /// `int32`.
    fn i32(&mut self) -> WireResult<i32> {
        Ok(i32::from_le_bytes(self.primitive()?))
    }
    /// `float32`.
    fn f32(&mut self) -> WireResult<f32> {
        Ok(f32::from_le_bytes(self.primitive()?))
    }
    /// `float64`.
    fn f64(&mut self) -> WireResult<f64> {
        Ok(f64::from_le_bytes(self.primitive()?))
    }
    /// `float64[N]` read as `N` consecutive `float64` fields (a pose's
    /// position and orientation): one bounds check for all of them.
    fn f64s<const N: usize>(&mut self) -> WireResult<[f64; N]>;
    /// Skips a `string` (u32 length, then that many bytes).
    fn skip_string(&mut self) -> WireResult<()> {
        let n = self.u32()? as usize;
        self.bytes(n).map(|_| ())
    }
}

/// Reader of ROS 1 serialised messages (packed, little-endian).
pub struct Ros1<'a>(Cursor<'a>);

impl<'a> Ros1<'a> {
    /// A reader at the start of `buf`.
    pub fn new(buf: &'a [u8]) -> Self {
        Ros1(Cursor { buf, pos: 0 })
    }

    /// Current offset in bytes.
    pub fn pos(&self) -> usize {
        self.0.pos
    }

    /// `time` (u32 seconds, u32 nanoseconds), as seconds.
    pub fn time(&mut self) -> WireResult<f64> {
        let sec = self.u32()?;
        let nsec = self.u32()?;
        Ok(sec as f64 + nsec as f64 * 1e-9)
    }
    /// `uint8[]`: u32 length then bytes.
    pub fn byte_array(&mut self) -> WireResult<&'a [u8]> {
        let n = self.u32()? as usize;
        self.bytes(n)
    }
}

impl<'a> RosReader<'a> for Ros1<'a> {
    fn f64s<const N: usize>(&mut self) -> WireResult<[f64; N]> {
        Ok(f64s_of(self.0.bytes(8 * N)?, true))
    }

    /// Packed, little-endian.
    fn primitive<const N: usize>(&mut self) -> WireResult<[u8; N]> {
        self.0.array()
    }

    fn bytes(&mut self, n: usize) -> WireResult<&'a [u8]> {
        self.0.bytes(n)
    }

    /// u32 length then bytes (not NUL-terminated).
    fn string(&mut self) -> WireResult<String> {
        let n = self.u32()? as usize;
        let b = self.bytes(n)?;
        Ok(String::from_utf8_lossy(b).into_owned())
    }

    /// (seq, stamp, frame_id).
    fn header(&mut self) -> WireResult<(f64, String)> {
        let _seq = self.u32()?;
        let t = self.time()?;
        let frame = self.string()?;
        Ok((t, frame))
    }

    fn header_stamp(&mut self) -> WireResult<f64> {
        let _seq = self.u32()?;
        let t = self.time()?;
        self.skip_string()?;
        Ok(t)
    }
}

/// Reader of ROS 2 CDR (XCDR1) messages: a 4-byte encapsulation header, then
/// primitives aligned to their size relative to the end of that header.
pub struct Cdr<'a> {
    cursor: Cursor<'a>,
    little: bool,
}

impl<'a> Cdr<'a> {
    fn header_stamp_only(&mut self) -> WireResult<f64> {
        let sec = self.i32()?;
        let nsec = self.u32()?;
        Ok(sec as f64 + nsec as f64 * 1e-9)
    }

    /// Reads the encapsulation header (`00 01` little-endian, `00 00` big-endian).
    pub fn new(buf: &'a [u8]) -> WireResult<Self> {
        if buf.len() < 4 {
            return Err(WireError::Truncated {
                offset: 0,
                need: 4,
                len: buf.len(),
            });
        }
        let little = match (buf[0], buf[1]) {
            (0, 1) | (0, 3) => true,
            (0, 0) | (0, 2) => false,
            (a, b) => {
                return Err(WireError::malformed(
                    0,
                    format!("unknown CDR encapsulation {a:#04x} {b:#04x}"),
                ))
            }
        };
        Ok(Cdr {
            cursor: Cursor {
                buf: &buf[4..],
                pos: 0,
            },
            little,
        })
    }
}

impl Cdr<'_> {
    /// Skips the padding before a primitive of `n` bytes.
    fn align(&mut self, n: usize) {
        let r = self.cursor.pos % n;
        if r != 0 {
            self.cursor.pos += n - r;
        }
    }
}

/// The `N` `float64` of `8 * N` bytes, in either byte order.
fn f64s_of<const N: usize>(b: &[u8], little: bool) -> [f64; N] {
    std::array::from_fn(|k| {
        let a: [u8; 8] = b[8 * k..8 * k + 8].try_into().unwrap_or_default();
        if little {
            f64::from_le_bytes(a)
        } else {
            f64::from_be_bytes(a)
        }
    })
}

impl<'a> RosReader<'a> for Cdr<'a> {
    /// The first aligned to 8; the others follow it unpadded.
    fn f64s<const N: usize>(&mut self) -> WireResult<[f64; N]> {
        self.align(8);
        Ok(f64s_of(self.cursor.bytes(8 * N)?, self.little))
    }

    /// Aligned to `N` from the end of the encapsulation header, swapped to
    /// little-endian from a big-endian message.
    fn primitive<const N: usize>(&mut self) -> WireResult<[u8; N]> {
        self.align(N);
        let mut a = self.cursor.array::<N>()?;
        if !self.little {
            a.reverse();
        }
        Ok(a)
    }

    fn bytes(&mut self, n: usize) -> WireResult<&'a [u8]> {
        self.cursor.bytes(n)
    }

    /// u32 length including the NUL, then bytes.
    fn string(&mut self) -> WireResult<String> {
        let n = self.u32()? as usize;
        let b = self.bytes(n)?;
        let b = b.strip_suffix(&[0]).unwrap_or(b);
        Ok(String::from_utf8_lossy(b).into_owned())
    }

    /// (stamp {int32 sec, uint32 nanosec}, frame_id).
    fn header(&mut self) -> WireResult<(f64, String)> {
        let t = self.header_stamp_only()?;
        let frame = self.string()?;
        Ok((t, frame))
    }

    fn header_stamp(&mut self) -> WireResult<f64> {
        let t = self.header_stamp_only()?;
        self.skip_string()?;
        Ok(t)
    }
}

/// One protobuf field value as it is on the wire.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PbValue<'a> {
    /// Wire type 0.
    Varint(u64),
    /// Wire type 1 (fixed64, sfixed64, double).
    Fixed64(u64),
    /// Wire type 2 (bytes, string, sub-message, packed).
    Bytes(&'a [u8]),
    /// Wire type 5 (fixed32, sfixed32, float).
    Fixed32(u32),
}

impl PbValue<'_> {
    /// A `double` field (0 for a varint, which a conforming writer never sends).
    pub fn as_f64(&self) -> WireResult<f64> {
        match self {
            PbValue::Fixed64(v) => Ok(f64::from_bits(*v)),
            other => Err(WireError::schema(format!(
                "expected a double, found {other:?}"
            ))),
        }
    }
    /// An integer field (varint, or fixed32/64).
    pub fn as_u64(&self) -> WireResult<u64> {
        match self {
            PbValue::Varint(v) | PbValue::Fixed64(v) => Ok(*v),
            PbValue::Fixed32(v) => Ok(*v as u64),
            PbValue::Bytes(_) => Err(WireError::schema("expected an integer, found bytes")),
        }
    }
    /// A length-delimited field.
    pub fn as_bytes(&self) -> WireResult<&[u8]> {
        match self {
            PbValue::Bytes(b) => Ok(b),
            other => Err(WireError::schema(format!(
                "expected bytes, found {other:?}"
            ))),
        }
    }
}

fn varint(buf: &[u8], pos: &mut usize) -> WireResult<u64> {
    let mut v: u64 = 0;
    for shift in (0..64).step_by(7) {
        let Some(&b) = buf.get(*pos) else {
            return Err(WireError::Truncated {
                offset: *pos,
                need: 1,
                len: buf.len(),
            });
        };
        *pos += 1;
        v |= ((b & 0x7f) as u64) << shift;
        if b & 0x80 == 0 {
            return Ok(v);
        }
    }
    Err(WireError::malformed(
        *pos,
        "protobuf varint longer than 10 bytes",
    ))
}

/// Iterates the (field number, value) pairs of a protobuf message.
pub struct PbFields<'a> {
    buf: &'a [u8],
    pos: usize,
}

/// Reads a protobuf message field by field.
pub fn pb_fields(buf: &[u8]) -> PbFields<'_> {
    PbFields { buf, pos: 0 }
}

impl<'a> Iterator for PbFields<'a> {
    type Item = WireResult<(u32, PbValue<'a>)>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.pos >= self.buf.len() {
            return None;
        }
        let r = self.field();
        if r.is_err() {
            self.pos = self.buf.len();
        }
        Some(r)
    }
}

impl<'a> PbFields<'a> {
    fn take(&mut self, n: usize) -> WireResult<&'a [u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.buf.len());
        match end {
            Some(end) => {
                let s = &self.buf[self.pos..end];
                self.pos = end;
                Ok(s)
            }
            None => Err(WireError::Truncated {
                offset: self.pos,
                need: n,
                len: self.buf.len(),
            }),
        }
    }

    fn field(&mut self) -> WireResult<(u32, PbValue<'a>)> {
        let start = self.pos;
        let key = varint(self.buf, &mut self.pos)?;
        let number = u32::try_from(key >> 3)
            .map_err(|_| WireError::malformed(start, "protobuf field number too large"))?;
        let value = match key & 7 {
            0 => PbValue::Varint(varint(self.buf, &mut self.pos)?),
            1 => {
                let b = self.take(8)?;
                let mut a = [0u8; 8];
                a.copy_from_slice(b);
                PbValue::Fixed64(u64::from_le_bytes(a))
            }
            2 => {
                let n = varint(self.buf, &mut self.pos)?;
                let n = usize::try_from(n)
                    .map_err(|_| WireError::malformed(self.pos, "protobuf length too large"))?;
                PbValue::Bytes(self.take(n)?)
            }
            5 => {
                let b = self.take(4)?;
                let mut a = [0u8; 4];
                a.copy_from_slice(b);
                PbValue::Fixed32(u32::from_le_bytes(a))
            }
            t => {
                return Err(WireError::malformed(
                    start,
                    format!("unsupported protobuf wire type {t}"),
                ))
            }
        };
        Ok((number, value))
    }
}

/// A minimal protobuf writer (proto3 encoding of the fields it is given).
#[derive(Default)]
pub struct PbWriter {
    /// The encoded message so far.
    pub buf: Vec<u8>,
}

impl PbWriter {
    /// An empty message.
    pub fn new() -> Self {
        PbWriter::default()
    }
    fn varint(&mut self, mut v: u64) {
        while v >= 0x80 {
            self.buf.push((v as u8) | 0x80);
            v >>= 7;
        }
        self.buf.push(v as u8);
    }
    fn key(&mut self, field: u32, wire: u8) {
        self.varint(((field as u64) << 3) | wire as u64);
    }
    /// A varint field (int32/int64/uint/enum; negative int32 as 10-byte two's complement).
    pub fn int(&mut self, field: u32, v: i64) {
        self.key(field, 0);
        self.varint(v as u64);
    }
    /// A `double` field.
    pub fn double(&mut self, field: u32, v: f64) {
        self.key(field, 1);
        self.buf.extend_from_slice(&v.to_bits().to_le_bytes());
    }
    /// A `fixed32` field.
    pub fn fixed32(&mut self, field: u32, v: u32) {
        self.key(field, 5);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// A `bytes` / `string` field.
    pub fn bytes(&mut self, field: u32, v: &[u8]) {
        self.key(field, 2);
        self.varint(v.len() as u64);
        self.buf.extend_from_slice(v);
    }
    /// The key and length of a `bytes` field of `len` bytes whose content
    /// the caller writes after [`PbWriter::buf`] (the message's last field,
    /// streamed rather than copied into the message).
    pub fn bytes_head(&mut self, field: u32, len: usize) {
        self.key(field, 2);
        self.varint(len as u64);
    }
    /// A sub-message field.
    pub fn message(&mut self, field: u32, m: &PbWriter) {
        self.bytes(field, &m.buf);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f64s_reads_what_f64_reads_field_by_field() {
        let v: [f64; 7] = [1.5, -2.25, 3.0e-9, 0.5, -0.5, 0.25, 1e300];
        // ROS 1: a u8 then the packed fields; CDR: the encapsulation, a u8,
        // padding to 8, the fields, in both byte orders.
        let mut ros1 = vec![7u8];
        ros1.extend(v.iter().flat_map(|x| x.to_le_bytes()));
        for little in [true, false] {
            let mut cdr = vec![0, u8::from(little), 0, 0, 7, 0, 0, 0, 0, 0, 0, 0];
            cdr.extend(v.iter().flat_map(|x| {
                if little {
                    x.to_le_bytes()
                } else {
                    x.to_be_bytes()
                }
            }));
            let mut a = Cdr::new(&cdr).unwrap();
            let mut b = Cdr::new(&cdr).unwrap();
            assert_eq!(a.u8().unwrap(), b.u8().unwrap());
            let one: Vec<f64> = (0..7).map(|_| b.f64().unwrap()).collect();
            assert_eq!(a.f64s::<7>().unwrap().to_vec(), one);
            assert_eq!(one, v);
            // One byte short: an error, not a partial read.
            let mut short = Cdr::new(&cdr[..cdr.len() - 1]).unwrap();
            short.u8().unwrap();
            assert!(short.f64s::<7>().is_err());
        }
        let mut r = Ros1::new(&ros1);
        r.u8().unwrap();
        assert_eq!(r.f64s::<7>().unwrap(), v);
        let mut short = Ros1::new(&ros1[..ros1.len() - 1]);
        short.u8().unwrap();
        assert!(short.f64s::<7>().is_err());
    }

    #[test]
    fn protobuf_round_trip() {
        let mut inner = PbWriter::new();
        inner.double(1, 1.5);
        let mut w = PbWriter::new();
        w.int(1, 300);
        w.message(2, &inner);
        w.fixed32(3, 16);
        w.int(4, -1);
        let fields: Vec<_> = pb_fields(&w.buf).collect::<WireResult<_>>().unwrap();
        assert_eq!(fields[0], (1, PbValue::Varint(300)));
        let sub: Vec<_> = pb_fields(fields[1].1.as_bytes().unwrap())
            .collect::<WireResult<_>>()
            .unwrap();
        assert_eq!(sub[0].1.as_f64().unwrap(), 1.5);
        assert_eq!(fields[2], (3, PbValue::Fixed32(16)));
        assert_eq!(fields[3].1.as_u64().unwrap() as i64, -1);
    }

    #[test]
    fn truncated_inputs_are_errors() {
        assert!(Ros1::new(&[1, 2, 3]).u32().is_err());
        assert!(Ros1::new(&[255, 255, 255, 255]).string().is_err());
        assert!(Cdr::new(&[0, 1]).is_err());
        assert!(Cdr::new(&[0, 1, 0, 0, 9]).unwrap().f64().is_err());
        assert!(pb_fields(&[0x0a, 0x05, 1]).next().unwrap().is_err());
        assert!(pb_fields(&[0xff; 12]).next().unwrap().is_err());
    }

    #[test]
    fn cdr_aligns_and_swaps() {
        // big-endian: u32 7, pad to 8, f64 2.0
        let mut b = vec![0, 0, 0, 0, 0, 0, 0, 7, 0, 0, 0, 0];
        b.extend_from_slice(&2.0f64.to_be_bytes());
        let mut c = Cdr::new(&b).unwrap();
        assert_eq!(c.u32().unwrap(), 7);
        assert_eq!(c.f64().unwrap(), 2.0);
    }
}
