//! LZ4 frames (as `roslz4` and MCAP writers make them) decompressed in one
//! call of liblz4's frame decoder, from the whole input straight into the
//! output vector.
//!
//! `lz4::Decoder` (a `Read`) copies the input into its own buffer a block at
//! a time, and each of its calls leaves liblz4 to copy the last 64 KiB of
//! output aside as the next block's dictionary: for frames of 64 KiB linked
//! blocks, a second copy of everything. Here liblz4 sees the whole input and
//! as much output room as there is, so it decodes block after block in place.

use std::ffi::CStr;

use lz4::liblz4::{
    LZ4FDecompressionContext, LZ4F_createDecompressionContext, LZ4F_decompress,
    LZ4F_freeDecompressionContext, LZ4F_getErrorName, LZ4F_isError, LZ4F_VERSION,
};

/// A decompression context, freed on drop.
struct Context(LZ4FDecompressionContext);

impl Context {
    fn new() -> Result<Context, String> {
        let mut ctx = LZ4FDecompressionContext(std::ptr::null_mut());
        // SAFETY: liblz4 writes a new context into `ctx` (or returns an error).
        let code = unsafe { LZ4F_createDecompressionContext(&mut ctx, LZ4F_VERSION) };
        check(code)?;
        Ok(Context(ctx))
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        // SAFETY: the context was made by LZ4F_createDecompressionContext and
        // is freed once.
        unsafe {
            LZ4F_freeDecompressionContext(LZ4FDecompressionContext(self.0 .0));
        }
    }
}

/// liblz4's error name for `code`, or the value it carries.
fn check(code: usize) -> Result<usize, String> {
    // SAFETY: both functions only read the code; the name is a static string.
    unsafe {
        if LZ4F_isError(code) != 0 {
            let name = CStr::from_ptr(LZ4F_getErrorName(code));
            return Err(name.to_string_lossy().into_owned());
        }
    }
    Ok(code)
}

/// Decompresses the LZ4 frame at the start of `data` into `out` (cleared
/// first), writing at most `limit` bytes: room for `ahead` bytes is reserved
/// first and doubled as needed, never past `limit`. Stops at the frame's end
/// (bytes after it are not read), when `limit` bytes are written, or when the
/// input ends inside the frame; the caller compares the length with what it
/// expects. An allocation that fails or a damaged frame is an error.
pub(crate) fn decompress_into(
    data: &[u8],
    ahead: usize,
    limit: usize,
    out: &mut Vec<u8>,
) -> Result<(), String> {
    out.clear();
    let reserve = |out: &mut Vec<u8>, n: usize| {
        out.try_reserve_exact(n)
            .map_err(|_| format!("cannot allocate {n} bytes for the decompressed data"))
    };
    reserve(out, ahead.clamp(1, limit.max(1)))?;
    let ctx = Context::new()?;
    let mut read = 0usize;
    while out.len() < limit {
        if out.len() == out.capacity() {
            let grown = (out.capacity() * 2).min(limit);
            reserve(out, grown - out.len())?;
        }
        let len = out.len();
        let spare = out.spare_capacity_mut();
        let mut dst_size = spare.len().min(limit - len);
        let mut src_size = data.len() - read;
        // SAFETY: liblz4 writes at most `dst_size` bytes at the start of the
        // spare capacity and reads at most `src_size` bytes of `data[read..]`;
        // without the stable-destination option it keeps no pointer into
        // `out` past the call (the dictionary is copied into the context).
        let code = unsafe {
            LZ4F_decompress(
                LZ4FDecompressionContext(ctx.0 .0),
                spare.as_mut_ptr().cast::<u8>(),
                &mut dst_size,
                data[read..].as_ptr(),
                &mut src_size,
                std::ptr::null(),
            )
        };
        let next = check(code)?;
        // SAFETY: the call wrote `dst_size` bytes after the initialised ones.
        unsafe { out.set_len(len + dst_size) };
        read += src_size;
        if next == 0 || (dst_size == 0 && src_size == 0) {
            // The frame's end, or the input ends inside it.
            break;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn frame(data: &[u8], block: lz4::BlockSize) -> Vec<u8> {
        let mut e = lz4::EncoderBuilder::new()
            .block_size(block)
            .build(Vec::new())
            .unwrap();
        e.write_all(data).unwrap();
        let (v, r) = e.finish();
        r.unwrap();
        v
    }

    #[test]
    fn frames_decompress_whole_or_stop_at_the_limit() {
        // Linked 64 KiB blocks over 1 MB, read with a small first reservation.
        let data: Vec<u8> = (0..1_000_000u32)
            .map(|i| (i % 251) as u8 ^ (i / 977) as u8)
            .collect();
        let f = frame(&data, lz4::BlockSize::Max64KB);
        let mut out = vec![9u8; 10];
        decompress_into(&f, 100, data.len() + 1, &mut out).unwrap();
        assert_eq!(out, data);
        // The same as lz4's own reader.
        let mut theirs = Vec::new();
        std::io::Read::read_to_end(&mut lz4::Decoder::new(&f[..]).unwrap(), &mut theirs).unwrap();
        assert_eq!(out, theirs);
        // At most `limit` bytes; a frame cut short gives what it holds.
        decompress_into(&f, 1 << 20, 1000, &mut out).unwrap();
        assert_eq!(out, &data[..1000]);
        decompress_into(&f[..f.len() / 2], 1 << 20, data.len() + 1, &mut out).unwrap();
        assert!(out.len() < data.len() && data.starts_with(&out));
        // Not a frame; an empty input.
        assert!(decompress_into(b"not an lz4 frame", 100, 100, &mut out).is_err());
        decompress_into(b"", 100, 100, &mut out).unwrap();
        assert!(out.is_empty());
    }
}
