//! OctoMap's voxel keys: 16 levels, `key = floor(coord · (1/resolution)) + 32768`
//! per axis, and their Morton (child-index) order.

/// Depth of the tree: 16 levels below the root, as in OctoMap's `OcTree`.
pub const TREE_DEPTH: u32 = 16;
/// Key of the voxel whose lower corner is the origin (`2^15`).
pub const TREE_MAX_VAL: i32 = 32768;

/// A voxel key `(kx, ky, kz)`, each in `0..65536`.
pub type Key = [u16; 3];

/// The key of one coordinate (metres), or `None` outside the tree
/// (OctoMap's `coordToKeyChecked`: `floor(resolution_factor · coord) + 32768`,
/// `resolution_factor = 1 / resolution` in `f64`).
#[inline]
pub fn coord_to_key(coord: f64, resolution_factor: f64) -> Option<u16> {
    let scaled = resolution_factor * coord;
    if !(scaled >= -(TREE_MAX_VAL as f64) && scaled < TREE_MAX_VAL as f64) {
        return None;
    }
    // floor() without a libm call: truncate, then step down for negative fractions.
    let t = scaled as i32;
    let f = if (t as f64) > scaled { t - 1 } else { t };
    Some((f + TREE_MAX_VAL) as u16)
}

/// The key of a point given in `f32` (as OctoMap's `point3d`), or `None` when
/// any axis lies outside the tree.
#[inline]
pub fn point_to_key(p: [f32; 3], resolution_factor: f64) -> Option<Key> {
    Some([
        coord_to_key(p[0] as f64, resolution_factor)?,
        coord_to_key(p[1] as f64, resolution_factor)?,
        coord_to_key(p[2] as f64, resolution_factor)?,
    ])
}

/// Centre coordinate (metres) of the voxel with key `k` at full depth
/// (OctoMap's `keyToCoord(key)`).
#[inline]
pub fn key_to_coord(k: u16, resolution: f64) -> f64 {
    ((k as i32 - TREE_MAX_VAL) as f64 + 0.5) * resolution
}

/// Centre coordinate (metres) of a node at `depth` (0 = root, 16 = voxel)
/// that contains key `k` (OctoMap's `keyToCoord(key, depth)`).
#[inline]
pub fn key_to_coord_at_depth(k: u16, depth: u32, resolution: f64) -> f64 {
    if depth == 0 {
        return 0.0;
    }
    if depth >= TREE_DEPTH {
        return key_to_coord(k, resolution);
    }
    let shift = TREE_DEPTH - depth;
    let size = resolution * f64::from(1u32 << shift);
    (((k as f64) - TREE_MAX_VAL as f64) / f64::from(1u32 << shift)).floor() * size + 0.5 * size
}

/// Every third bit for each byte value (bit `i` of the byte to bit `3i`).
const SPREAD8: [u64; 256] = {
    let mut t = [0u64; 256];
    let mut v = 0;
    while v < 256 {
        let mut i = 0;
        while i < 8 {
            t[v] |= (((v >> i) & 1) as u64) << (3 * i);
            i += 1;
        }
        v += 1;
    }
    t
};

/// Spreads the 16 bits of `v` to every third bit of a 48-bit word.
#[inline]
fn spread(v: u16) -> u64 {
    SPREAD8[(v & 0xFF) as usize] | (SPREAD8[(v >> 8) as usize] << 24)
}

/// Gathers every third bit of `x` (the inverse of [`spread`]).
#[inline]
fn compact(mut x: u64) -> u16 {
    x &= 0x2492_4924_9249;
    x = (x | (x >> 2)) & 0x0C30_C30C_30C3;
    x = (x | (x >> 4)) & 0x00F0_0F00_F00F;
    x = (x | (x >> 8)) & 0x0000_FF00_00FF;
    x = (x | (x >> 16)) & 0xFFFF;
    x as u16
}

/// Morton code of a key: bit `3b` is bit `b` of x, `3b+1` of y, `3b+2` of z,
/// so that `(code >> 3·(15 − depth)) & 7` is OctoMap's child index
/// (`x + 2y + 4z`) at `depth`, and sorting codes gives OctoMap's depth-first
/// child order.
#[inline]
pub fn morton(k: Key) -> u64 {
    spread(k[0]) | (spread(k[1]) << 1) | (spread(k[2]) << 2)
}

/// The key of a Morton code (inverse of [`morton`]).
#[inline]
pub fn from_morton(code: u64) -> Key {
    [compact(code), compact(code >> 1), compact(code >> 2)]
}

/// Child index (0..8) of `key` below a node at `depth` (OctoMap's `computeChildIdx`).
#[inline]
pub fn child_index(k: Key, depth: u32) -> usize {
    let bit = TREE_DEPTH - 1 - depth;
    (((k[0] >> bit) & 1) | (((k[1] >> bit) & 1) << 1) | (((k[2] >> bit) & 1) << 2)) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_round_trip_and_child_order() {
        for k in [
            [0u16, 0, 0],
            [1, 2, 3],
            [65535, 0, 32768],
            [12345, 54321, 777],
        ] {
            let c = morton(k);
            assert_eq!(from_morton(c), k);
            for d in 0..TREE_DEPTH {
                assert_eq!(((c >> (3 * (15 - d))) & 7) as usize, child_index(k, d));
            }
        }
    }

    #[test]
    fn keys_at_negative_coordinates() {
        let f = 1.0 / 0.1;
        assert_eq!(coord_to_key(0.0, f), Some(32768));
        assert_eq!(coord_to_key(-1e-9, f), Some(32767));
        assert_eq!(coord_to_key(-0.1, f), Some(32767));
        assert_eq!(coord_to_key(-0.1000001, f), Some(32766));
        assert_eq!(coord_to_key(3276.75, f), Some(65535));
        assert_eq!(coord_to_key(3276.8, f), None);
        assert_eq!(coord_to_key(-3276.8, f), Some(0));
        assert_eq!(coord_to_key(-3276.81, f), None);
        assert_eq!(coord_to_key(f64::NAN, f), None);
    }
}
