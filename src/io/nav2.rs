//! nav2 `map_server` files of a 2-D grid: `map.pgm` + `map.yaml`, and the
//! height of each cell beside them (`map_height.npy`).
//!
//! - `map.pgm`: binary PGM (`P5`, 8 bit), row 0 at the top (the highest y),
//!   as `map_server` reads it (its `loadMapFromFile` puts image row `y` at
//!   grid row `height − 1 − y`). Trinary values as `map_saver` writes them:
//!   0 occupied, 254 free, 205 unknown.
//! - `map.yaml`: exactly the fields `map_server` documents and reads —
//!   `image`, `mode: trinary`, `resolution`, `origin: [x, y, yaw]` (the
//!   lower-left corner of the lower-left cell, yaw 0), `negate: 0`,
//!   `occupied_thresh: 0.65`, `free_thresh: 0.196`.
//! - `map_height.npy`: NumPy `<f4` array of shape `(height, width)` in the
//!   image's row order (row 0 at the top, pixel for pixel with `map.pgm`): the
//!   centre height (metres, world z) of the highest occupied voxel of each
//!   cell, NaN where none.
//!
//! The thresholds are those `map_server` applies to a pixel's darkness
//! `occ = (255 − value) / 255`: occupied when `occ > occupied_thresh`, free
//! when `occ < free_thresh`, else unknown. `map_saver`'s own default
//! `free_thresh: 0.25` would load its unknown pixels (205: `occ = 0.196`) as
//! free space; 0.196 (what ROS 1's `map_saver` wrote) keeps them unknown,
//! and 0.65 keeps occupied pixels (`occ = 1`) occupied and free ones
//! (`occ = 0.004`) free. Which cells are occupied is decided before, by the
//! grid's probability against a threshold (the octree's own 0.5 by default).
//!
//! Each file is written atomically ([`crate::io::atomic`]), the YAML last.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::atomic::{write_bytes_atomic, OutputSet};
use crate::map::Grid2d;

/// `occupied_thresh` written into `map.yaml`.
pub const OCCUPIED_THRESH: f64 = 0.65;
/// `free_thresh` written into `map.yaml` (see the module documentation).
pub const FREE_THRESH: f64 = 0.196;
/// Pixel of an occupied cell.
pub const PIXEL_OCCUPIED: u8 = 0;
/// Pixel of a free cell.
pub const PIXEL_FREE: u8 = 254;
/// Pixel of an unknown cell.
pub const PIXEL_UNKNOWN: u8 = 205;

/// The three files of one grid.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Nav2Files {
    /// The occupancy image (`.pgm`).
    pub image: PathBuf,
    /// The metadata `map_server` loads (`.yaml`).
    pub yaml: PathBuf,
    /// The height layer (`.npy`).
    pub height: PathBuf,
}

impl Nav2Files {
    /// The file names for `target`: an existing folder (or a path ending in
    /// `/`) gets `map.pgm`, `map.yaml` and `map_height.npy` inside it; any
    /// other path is a prefix as `map_saver -f` takes it (`out/floor` gives
    /// `out/floor.pgm`, `out/floor.yaml`, `out/floor_height.npy`), a
    /// trailing `.yaml` or `.pgm` dropped first.
    pub fn for_target(target: &Path) -> Nav2Files {
        let as_dir = target.is_dir() || target.as_os_str().to_string_lossy().ends_with('/');
        let prefix = if as_dir {
            target.join("map")
        } else {
            match target.extension().and_then(|e| e.to_str()) {
                Some("yaml" | "pgm") => target.with_extension(""),
                _ => target.to_path_buf(),
            }
        };
        let with = |suffix: &str| {
            let mut s = prefix.clone().into_os_string();
            s.push(suffix);
            PathBuf::from(s)
        };
        Nav2Files {
            image: with(".pgm"),
            yaml: with(".yaml"),
            height: with("_height.npy"),
        }
    }
}

/// Checks an occupancy threshold: a probability in `(0, 1]`.
fn check_threshold(threshold: f64) -> Result<()> {
    if threshold > 0.0 && threshold <= 1.0 {
        Ok(())
    } else {
        Err(Error::invalid(
            "occupied_threshold",
            format!("{threshold} is not a probability in (0, 1]"),
        ))
    }
}

/// The trinary pixel of a cell of probability `p` (NaN unknown), compared
/// with the threshold in `f32` as [`Grid2d::states`] does.
fn pixel(p: f32, threshold: f32) -> u8 {
    if p.is_nan() {
        PIXEL_UNKNOWN
    } else if p >= threshold {
        PIXEL_OCCUPIED
    } else {
        PIXEL_FREE
    }
}

/// The `map.pgm` bytes: `P5`, width × height, maxval 255, row 0 at the top;
/// cells of probability ≥ `occupied_threshold` occupied, other known cells free.
pub fn pgm_bytes(grid: &Grid2d, occupied_threshold: f64) -> Result<Vec<u8>> {
    check_threshold(occupied_threshold)?;
    check_grid(grid)?;
    let header = format!("P5\n{} {}\n255\n", grid.width, grid.height);
    let mut out = Vec::with_capacity(header.len() + grid.width * grid.height);
    out.extend_from_slice(header.as_bytes());
    for row in grid.probability.chunks_exact(grid.width).rev() {
        out.extend(row.iter().map(|&p| pixel(p, occupied_threshold as f32)));
    }
    Ok(out)
}

/// A number as YAML reads it back to the same `f64` (shortest round trip; no
/// negative zero).
fn yaml_number(x: f64) -> String {
    format!("{}", x + 0.0)
}

/// A YAML scalar for a file name: plain when it is made of safe characters,
/// single-quoted otherwise.
fn yaml_string(s: &str) -> String {
    let plain = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-' | '+'))
        && !s.starts_with(['-', '.']);
    if plain {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "''"))
    }
}

/// The `map.yaml` text for an image file named `image` (relative to the
/// YAML's folder, as `map_server` resolves it).
pub fn yaml_text(grid: &Grid2d, image: &str) -> String {
    format!(
        "image: {}\nmode: trinary\nresolution: {}\norigin: [{}, {}, 0]\nnegate: 0\n\
         occupied_thresh: {OCCUPIED_THRESH}\nfree_thresh: {FREE_THRESH}\n",
        yaml_string(image),
        yaml_number(grid.resolution),
        yaml_number(grid.origin[0]),
        yaml_number(grid.origin[1]),
    )
}

/// The `map_height.npy` bytes: NPY 1.0, `<f4`, C order, shape
/// `(height, width)`, row 0 at the top (as the image).
pub fn height_npy_bytes(grid: &Grid2d) -> Result<Vec<u8>> {
    check_grid(grid)?;
    let dict = format!(
        "{{'descr': '<f4', 'fortran_order': False, 'shape': ({}, {}), }}",
        grid.height, grid.width
    );
    // Magic (6) + version (2) + header length (2) + dict + padding + '\n',
    // a multiple of 64 bytes.
    let unpadded = 10 + dict.len() + 1;
    let total = unpadded.div_ceil(64) * 64;
    let mut header = dict;
    header.extend(std::iter::repeat_n(' ', total - unpadded));
    header.push('\n');
    let mut out = Vec::with_capacity(total + 4 * grid.top_z.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for row in grid.top_z.chunks_exact(grid.width).rev() {
        for v in row {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    Ok(out)
}

/// A grid the writers can take: not empty, layers of `width · height` cells.
fn check_grid(grid: &Grid2d) -> Result<()> {
    if grid.is_empty() {
        return Err(Error::invalid(
            "grid",
            format!(
                "empty ({} x {} cells): no known voxel in z [{}, {}]",
                grid.width, grid.height, grid.z_band[0], grid.z_band[1]
            ),
        ));
    }
    let cells = grid.width.checked_mul(grid.height);
    for (what, layer) in [("probability", &grid.probability), ("top_z", &grid.top_z)] {
        if cells != Some(layer.len()) {
            return Err(Error::ShapeMismatch {
                what: what.into(),
                expected: format!("{} x {} cells", grid.height, grid.width),
                got: format!("{} values", layer.len()),
            });
        }
    }
    if !(grid.resolution.is_finite() && grid.resolution > 0.0) {
        return Err(Error::invalid(
            "resolution",
            format!("{} is not a positive length", grid.resolution),
        ));
    }
    if let Some(i) = grid.origin.iter().position(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "origin".into(),
            index: i,
        });
    }
    Ok(())
}

/// Writes the `map_server` files of `grid` for `target` (see
/// [`Nav2Files::for_target`]): the image and the height layer first, the
/// YAML last, each atomically. Cells of probability ≥ `occupied_threshold`
/// are occupied (the octree's rule is 0.5). An empty grid is refused.
pub fn write_nav2(grid: &Grid2d, target: &Path, occupied_threshold: f64) -> Result<Nav2Files> {
    let files = Nav2Files::for_target(target);
    for (path, bytes) in nav2_bytes(grid, &files, occupied_threshold)? {
        write_bytes_atomic(&path, &bytes)?;
    }
    Ok(files)
}

/// The `map_server` files of `grid` as outputs of `set` (published with the
/// set's other outputs by [`OutputSet::commit`]).
pub fn write_nav2_into(
    set: &mut OutputSet,
    grid: &Grid2d,
    files: &Nav2Files,
    occupied_threshold: f64,
) -> Result<()> {
    for (path, bytes) in nav2_bytes(grid, files, occupied_threshold)? {
        set.write_bytes(&path, &bytes)?;
    }
    Ok(())
}

/// The image, the height layer and the YAML of `grid` (in that order, the
/// YAML last), with their paths.
fn nav2_bytes(
    grid: &Grid2d,
    files: &Nav2Files,
    occupied_threshold: f64,
) -> Result<[(PathBuf, Vec<u8>); 3]> {
    let pgm = pgm_bytes(grid, occupied_threshold)?;
    let npy = height_npy_bytes(grid)?;
    let image_name = files
        .image
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| {
            Error::invalid(
                "path",
                format!("{}: the image name is not UTF-8", files.image.display()),
            )
        })?
        .to_string();
    Ok([
        (files.image.clone(), pgm),
        (files.height.clone(), npy),
        (
            files.yaml.clone(),
            yaml_text(grid, &image_name).into_bytes(),
        ),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> Grid2d {
        Grid2d {
            resolution: 0.1,
            origin: [-0.3, 0.2],
            width: 3,
            height: 2,
            z_band: [0.1, 1.0],
            // row 0 (y lowest): occupied, free, unknown; row 1: free, occupied (0.5), 0.4
            probability: vec![0.9, 0.2, f32::NAN, 0.1, 0.5, 0.4],
            top_z: vec![0.85, f32::NAN, f32::NAN, f32::NAN, 0.15, f32::NAN],
        }
    }

    #[test]
    fn pgm_puts_the_highest_row_first_with_trinary_values() {
        let b = pgm_bytes(&grid(), 0.5).unwrap();
        let header = b"P5\n3 2\n255\n";
        assert_eq!(&b[..header.len()], header);
        assert_eq!(&b[header.len()..], &[254, 0, 254, 0, 254, 205]);
        // A stricter threshold frees the 0.5 cell.
        let b = pgm_bytes(&grid(), 0.65).unwrap();
        assert_eq!(&b[header.len()..], &[254, 254, 254, 0, 254, 205]);
        assert!(pgm_bytes(&grid(), 0.0).is_err());
        assert!(pgm_bytes(&grid(), f64::NAN).is_err());
    }

    #[test]
    fn yaml_has_the_map_server_fields() {
        let y = yaml_text(&grid(), "map.pgm");
        assert_eq!(
            y,
            "image: map.pgm\nmode: trinary\nresolution: 0.1\norigin: [-0.3, 0.2, 0]\n\
             negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
        );
        assert_eq!(yaml_string("my map.pgm"), "'my map.pgm'");
        assert_eq!(yaml_string("it's.pgm"), "'it''s.pgm'");
        assert_eq!(yaml_number(-0.0), "0");
    }

    #[test]
    fn map_server_reads_every_pixel_back_as_written() {
        // map_server's trinary rule on a pixel's darkness.
        let load = |v: u8| {
            let occ = 1.0 - f64::from(v) / 255.0;
            if OCCUPIED_THRESH < occ {
                100
            } else if occ < FREE_THRESH {
                0
            } else {
                -1
            }
        };
        assert_eq!(load(PIXEL_OCCUPIED), 100);
        assert_eq!(load(PIXEL_FREE), 0);
        assert_eq!(load(PIXEL_UNKNOWN), -1);
        // With map_saver's default free_thresh the unknown pixel would load as free.
        assert!(1.0 - f64::from(PIXEL_UNKNOWN) / 255.0 < 0.25);
    }

    #[test]
    fn npy_header_is_aligned_and_rows_flipped() {
        let b = height_npy_bytes(&grid()).unwrap();
        assert_eq!(&b[..8], b"\x93NUMPY\x01\x00");
        let hl = u16::from_le_bytes([b[8], b[9]]) as usize;
        assert_eq!((10 + hl) % 64, 0);
        assert_eq!(b[10 + hl - 1], b'\n');
        let data: Vec<f32> = b[10 + hl..]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        assert_eq!(data.len(), 6);
        assert_eq!(data[1], 0.15);
        assert_eq!(data[0].to_bits(), f32::NAN.to_bits());
        assert_eq!(data[3], 0.85);
    }

    #[test]
    fn targets_are_folders_or_prefixes() {
        let dir = tempfile::tempdir().unwrap();
        let f = Nav2Files::for_target(dir.path());
        assert_eq!(f.image, dir.path().join("map.pgm"));
        assert_eq!(f.height, dir.path().join("map_height.npy"));
        let f = Nav2Files::for_target(&dir.path().join("floor.yaml"));
        assert_eq!(f.yaml, dir.path().join("floor.yaml"));
        assert_eq!(f.image, dir.path().join("floor.pgm"));
        let f = Nav2Files::for_target(&dir.path().join("floor"));
        assert_eq!(f.height, dir.path().join("floor_height.npy"));
    }

    #[test]
    fn empty_and_inconsistent_grids_are_refused() {
        let mut g = grid();
        g.width = 0;
        g.height = 0;
        assert!(matches!(
            pgm_bytes(&g, 0.5),
            Err(Error::InvalidArgument { ref what, .. }) if what == "grid"
        ));
        let mut g = grid();
        g.top_z.pop();
        assert!(matches!(
            height_npy_bytes(&g),
            Err(Error::ShapeMismatch { ref what, .. }) if what == "top_z"
        ));
    }
}
