//! References by image name: COLMAP `model_aligner`'s `--ref_images_path`
//! file (`name x y z` a line), and image names that are time stamps.

use std::path::Path;

use nalgebra::Vector3;

use crate::error::{Error, Result};

/// A position (world frame, metres for a reference) known for one image.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedPosition {
    /// The image name, as the model's `images` file spells it.
    pub name: String,
    /// The position.
    pub position: Vector3<f64>,
}

/// Reads a reference file of `name x y z` lines, as COLMAP's `model_aligner`
/// takes it, and its common variants: fields separated by white space or by
/// commas (decided by the first record: a comma there means CSV), `#` comment
/// lines, and one header line before the first record (a first record whose
/// `x y z` are not numbers is taken as the header). Every record must have
/// exactly four fields with finite coordinates; a name given twice is refused.
pub fn read_name_positions(path: &Path) -> Result<Vec<NamedPosition>> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::parse(path, 0, "not a regular file"));
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = super::text::utf8(path, &bytes)?;
    let mut comma = None;
    let mut out: Vec<NamedPosition> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    let mut first = true;
    for (k, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let comma = *comma.get_or_insert_with(|| line.contains(','));
        let fields: Vec<&str> = if comma {
            line.split(',').map(str::trim).collect()
        } else {
            line.split_whitespace().collect()
        };
        let is_first = std::mem::replace(&mut first, false);
        let coords: Option<Vec<f64>> = fields
            .get(1..)
            .map(|f| {
                f.iter()
                    .map(|v| v.parse::<f64>().ok())
                    .collect::<Option<Vec<f64>>>()
            })
            .unwrap_or(None);
        if is_first && coords.is_none() {
            continue; // the header line
        }
        if fields.len() != 4 {
            return Err(Error::parse(
                path,
                k + 1,
                format!("expected 4 fields (name x y z), got {}", fields.len()),
            ));
        }
        let c = coords.ok_or_else(|| {
            Error::parse(
                path,
                k + 1,
                format!("x y z are not numbers: {:?}", &fields[1..]),
            )
        })?;
        if c.iter().any(|v| !v.is_finite()) {
            return Err(Error::parse(path, k + 1, "x y z must be finite"));
        }
        if !seen.insert(fields[0].to_owned()) {
            return Err(Error::parse(
                path,
                k + 1,
                format!("image {:?} is listed twice", fields[0]),
            ));
        }
        out.push(NamedPosition {
            name: fields[0].to_owned(),
            position: Vector3::new(c[0], c[1], c[2]),
        });
    }
    if out.is_empty() {
        return Err(Error::parse(path, 0, "no `name x y z` records"));
    }
    Ok(out)
}

/// The time (seconds) an image name stands for, if it is a time stamp: the
/// file name without folders and extension (`cam0/1403636579763555584.png` →
/// `1403636579763555584`) that is either digits or digits with one decimal
/// point (seconds, as TUM RGB-D does: `1305031102.175304.png`). Digits are
/// read in the one unit that makes them Unix time (1973 to 2103): seconds (10
/// digits), milliseconds (13), microseconds (16) or nanoseconds (19, as EuRoC
/// names its images); digits that are no Unix time in any unit are
/// nanoseconds when there are 16 to 20 of them (a clock since boot), else no
/// stamp. Integers convert exactly to the nearest `f64` second. Anything else
/// (`frame_0001.jpg`, `00.jpg`) is not a stamp.
pub fn image_name_time(name: &str) -> Option<f64> {
    let file = name.rsplit(['/', '\\']).next().unwrap_or(name);
    let stem = match file.rfind('.') {
        Some(i) if file[i + 1..].chars().any(|c| !c.is_ascii_digit()) || i + 1 == file.len() => {
            &file[..i]
        }
        _ => file,
    };
    if stem.is_empty() {
        return None;
    }
    let digits = stem.bytes().filter(u8::is_ascii_digit).count();
    let dots = stem.bytes().filter(|&b| b == b'.').count();
    if digits + dots != stem.len() {
        return None;
    }
    match dots {
        0 if stem.len() <= 20 => {
            let v: u128 = stem.parse().ok()?;
            // Ticks per second of the unit that makes the value Unix time.
            let per_second = [1u128, 1_000, 1_000_000, 1_000_000_000]
                .into_iter()
                .find(|&k| (100_000_000..=4_200_000_000).contains(&(v / k)))
                .or_else(|| (16..=20).contains(&stem.len()).then_some(1_000_000_000))?;
            let (s, rem) = (v / per_second, v % per_second);
            Some(s as f64 + rem as f64 / per_second as f64)
        }
        1 if !stem.starts_with('.') && !stem.ends_with('.') => stem.parse().ok(),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_that_are_stamps() {
        let t = image_name_time("cam0/data/1403636579763555584.png").unwrap();
        assert!((t - 1_403_636_579.763_555_5).abs() < 1e-6);
        assert_eq!(
            image_name_time("1305031102.175304.png"),
            Some(1305031102.175304)
        );
        assert_eq!(
            image_name_time("1305031102.175304"),
            Some(1305031102.175304)
        );
        // Unix time in milliseconds, microseconds and whole seconds; a clock since boot in ns.
        let ms = image_name_time("1403636579763.jpg").unwrap();
        assert!((ms - 1_403_636_579.763).abs() < 1e-6, "{ms}");
        let us = image_name_time("img/1403636579763555.png").unwrap();
        assert!((us - 1_403_636_579.763_555).abs() < 1e-6, "{us}");
        assert_eq!(image_name_time("1403636579.png"), Some(1_403_636_579.0));
        let boot = image_name_time("0000123456789012345.png").unwrap();
        assert!((boot - 123_456_789.012_345).abs() < 1e-6, "{boot}");
        assert_eq!(image_name_time("000123.png"), None);
        assert_eq!(image_name_time("123456789012345678901.png"), None);
        assert_eq!(image_name_time("00.jpg"), None);
        assert_eq!(image_name_time("frame_000123.png"), None);
        assert_eq!(image_name_time("1403636579763555584_left.png"), None);
        assert_eq!(image_name_time(""), None);
    }
}
