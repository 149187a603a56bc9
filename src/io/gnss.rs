//! GNSS fixes from text: NMEA 0183 receiver logs and CSV/TXT tables.
//!
//! **NMEA** (`$GPGGA`, `$GNGGA`, … any talker): `GGA` gives the fixes (fix
//! quality 0 = no fix: dropped and counted), `GST` their accuracy (the
//! latitude, longitude and altitude standard deviations become a diagonal ENU
//! covariance, m²), `RMC` / `ZDA` the date. Every sentence's checksum is
//! checked. The height is the GGA altitude (above the geoid) plus its geoid
//! separation: metres above the WGS84 ellipsoid. GGA carries only the time of
//! day: with a date from RMC or ZDA anywhere in the file the times are Unix
//! seconds (UTC); without one they count from 00:00 UTC of the first fix's day
//! ([`TimeBase::TimeOfDay`]). Text before a sentence's `$` and lines with no
//! `$` (a log's truncated first line) are skipped.
//!
//! **CSV/TXT**: one fix per line, `time, lat, lon, alt` then optionally the
//! ENU position covariance as 3 variances (`var_e, var_n, var_u`, m²) or 9
//! values (row-major 3×3, m², as `NavSatFix.position_covariance`); time in
//! seconds, latitude and longitude in degrees, altitude in metres **above the
//! WGS84 ellipsoid**. Comma or whitespace separated; lines starting with `#`
//! are comments; the first other line may be a header (no number in it).
//!
//! Lines are read with a bound ([`MAX_LINE`]): a longer line is a format
//! error, so a file without line breaks (`/dev/zero`) cannot grow memory.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Result};
use crate::geo::{FixStatus, GnssFix, GnssFixes, TimeBase};
use crate::io::lines::head;

/// The longest line accepted, bytes (an NMEA sentence has at most 82, a CSV
/// row of 13 doubles about 350).
pub const MAX_LINE: usize = 4096;

/// A GNSS file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GnssFormat {
    /// NMEA 0183 sentences.
    Nmea,
    /// `time, lat, lon, alt[, covariance]` rows.
    Csv,
    /// An MCAP log with a `sensor_msgs/NavSatFix` or `foxglove.LocationFix` topic.
    Mcap,
}

impl GnssFormat {
    /// `"nmea"`, `"csv"` (also `"txt"`), `"mcap"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name.to_ascii_lowercase().as_str() {
            "nmea" => Ok(GnssFormat::Nmea),
            "csv" | "txt" => Ok(GnssFormat::Csv),
            "mcap" => Ok(GnssFormat::Mcap),
            _ => Err(Error::invalid(
                "format",
                format!("{name:?}: expected \"nmea\", \"csv\" or \"mcap\""),
            )),
        }
    }

    /// The format of a file from its first bytes: the MCAP magic, a line
    /// holding `$` followed by a sentence name and a comma (NMEA), else CSV.
    pub fn detect(path: &Path) -> Result<Self> {
        Ok(Self::of_head(&head(path)?))
    }

    /// [`GnssFormat::detect`] of a file's first bytes.
    fn of_head(head: &[u8]) -> Self {
        if head.starts_with(b"\x89MCAP0\r\n") {
            return GnssFormat::Mcap;
        }
        let nmea = head.split(|&b| b == b'\n').any(|line| {
            line.iter().position(|&b| b == b'$').is_some_and(|i| {
                let rest = &line[i + 1..];
                rest.len() > 6 && rest[..5].iter().all(u8::is_ascii_alphanumeric) && rest[5] == b','
            })
        });
        if nmea {
            GnssFormat::Nmea
        } else {
            GnssFormat::Csv
        }
    }

    /// The format of a text file of fixes, `None` for a file that is none
    /// (a trajectory file): NMEA as [`GnssFormat::detect`] finds it; CSV when
    /// the first row that is no comment or header has 4, 7 or 13 fields with
    /// a latitude and longitude in range (a TUM or EuRoC row has 8 or 17).
    pub fn sniff_text(path: &Path) -> Result<Option<Self>> {
        let head = head(path)?;
        match Self::of_head(&head) {
            GnssFormat::Nmea => return Ok(Some(GnssFormat::Nmea)),
            GnssFormat::Mcap => return Ok(None),
            GnssFormat::Csv => {}
        }
        let text = String::from_utf8_lossy(&head);
        let mut first = true;
        for line in text.lines() {
            let t = line.trim();
            if t.is_empty() || t.starts_with('#') {
                continue;
            }
            let tokens = fields(t);
            let values: Vec<Option<f64>> = tokens.iter().map(|s| s.parse::<f64>().ok()).collect();
            if first && values.iter().all(Option::is_none) {
                first = false; // a header
                continue;
            }
            let in_range = matches!(
                values.get(1..3),
                Some([Some(lat), Some(lon)]) if lat.abs() <= 90.0 && lon.abs() <= 180.0
            );
            return Ok((matches!(tokens.len(), 4 | 7 | 13) && in_range).then_some(GnssFormat::Csv));
        }
        Ok(None)
    }
}

/// The fields of a CSV / TXT row of fixes: comma-separated when it holds a
/// comma, else whitespace-separated.
fn fields(t: &str) -> Vec<&str> {
    if t.contains(',') {
        t.split(',').map(str::trim).collect()
    } else {
        t.split_whitespace().collect()
    }
}

/// A line reader that refuses lines longer than [`MAX_LINE`].
struct Lines<R> {
    inner: R,
    buf: Vec<u8>,
    line: usize,
    path: PathBuf,
}

impl<R: BufRead> Lines<R> {
    fn new(inner: R, path: &Path) -> Self {
        Lines {
            inner,
            buf: Vec::with_capacity(256),
            line: 0,
            path: path.to_path_buf(),
        }
    }

    fn err(&self, reason: impl Into<String>) -> Error {
        Error::parse(&self.path, self.line, reason)
    }

    /// The next line without its line break, `None` at the end.
    fn next_line(&mut self) -> Result<Option<String>> {
        self.buf.clear();
        self.line += 1;
        let n = (&mut self.inner)
            .take(MAX_LINE as u64 + 1)
            .read_until(b'\n', &mut self.buf)
            .map_err(|e| Error::io(&self.path, e))?;
        if n == 0 {
            return Ok(None);
        }
        if self.buf.last() == Some(&b'\n') {
            self.buf.pop();
        } else if self.buf.len() > MAX_LINE {
            return Err(self.err(format!(
                "line longer than {MAX_LINE} bytes: not a GNSS text file"
            )));
        }
        if self.buf.last() == Some(&b'\r') {
            self.buf.pop();
        }
        match std::str::from_utf8(&self.buf) {
            Ok(s) => Ok(Some(s.to_owned())),
            Err(e) => Err(Error::parse(
                &self.path,
                self.line,
                format!("not UTF-8 text at byte {} of the line", e.valid_up_to()),
            )),
        }
    }
}

fn open(path: &Path) -> Result<BufReader<File>> {
    File::open(path)
        .map(|f| BufReader::with_capacity(1 << 16, f))
        .map_err(|e| Error::io(path, e))
}

/// Reads GNSS fixes from `path`: NMEA, CSV or MCAP (`format = None`: found by
/// [`GnssFormat::detect`]). `geoid_offset` (m, the geoid height N at the site)
/// is added to altitudes given above the geoid: every CSV altitude, and NMEA
/// GGA altitudes whose sentence leaves its own geoid separation empty. MCAP
/// altitudes are taken as they are (`NavSatFix` altitudes are ellipsoidal).
pub fn read_gnss(
    path: impl AsRef<Path>,
    format: Option<GnssFormat>,
    geoid_offset: f64,
) -> Result<GnssFixes> {
    let path = path.as_ref();
    if !geoid_offset.is_finite() {
        return Err(Error::invalid(
            "geoid_offset",
            format!("{geoid_offset}: expected finite metres"),
        ));
    }
    let format = match format {
        Some(f) => f,
        None => GnssFormat::detect(path)?,
    };
    match format {
        GnssFormat::Nmea => read_nmea(path, geoid_offset),
        GnssFormat::Csv => read_gnss_csv(path, geoid_offset),
        GnssFormat::Mcap => crate::io::mcap::gnss_decode::read_gnss_mcap(path, None),
    }
}

/// Reads a CSV/TXT of fixes (format in the module doc).
pub fn read_gnss_csv(path: impl AsRef<Path>, geoid_offset: f64) -> Result<GnssFixes> {
    let path = path.as_ref();
    parse_gnss_csv(open(path)?, path, geoid_offset)
}

/// [`read_gnss_csv`] from any reader; `path` names the source in errors.
pub fn parse_gnss_csv(reader: impl BufRead, path: &Path, geoid_offset: f64) -> Result<GnssFixes> {
    let mut lines = Lines::new(reader, path);
    let mut fixes = Vec::new();
    let mut columns: Option<usize> = None;
    let mut seen_row = false;
    const NAMES: [&str; 4] = ["time", "lat", "lon", "alt"];
    while let Some(line) = lines.next_line()? {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let tokens = fields(t);
        let values: Vec<Option<f64>> = tokens.iter().map(|s| s.parse::<f64>().ok()).collect();
        if !seen_row && values.iter().all(Option::is_none) {
            seen_row = true; // a header
            continue;
        }
        seen_row = true;
        let n = tokens.len();
        if !matches!(n, 4 | 7 | 13) {
            return Err(lines.err(format!(
                "{n} columns: expected time, lat, lon, alt and optionally 3 variances or 9 covariance values (4, 7 or 13)"
            )));
        }
        match columns {
            None => columns = Some(n),
            Some(c) if c != n => {
                return Err(lines.err(format!("{n} columns where the first row has {c}")))
            }
            _ => {}
        }
        let mut v = [0.0; 13];
        for (k, (tok, val)) in tokens.iter().zip(&values).enumerate() {
            v[k] = val.ok_or_else(|| {
                let name = NAMES.get(k).copied().unwrap_or("covariance");
                lines.err(format!(
                    "column {} ({name}): {tok:?} is not a number",
                    k + 1
                ))
            })?;
        }
        let covariance = match n {
            7 => Some(Matrix3::from_diagonal(&Vector3::new(v[4], v[5], v[6]))),
            13 => Some(Matrix3::from_row_slice(&v[4..13])),
            _ => None,
        };
        fixes.push(GnssFix {
            time: v[0],
            lat: v[1],
            lon: v[2],
            alt: v[3] + geoid_offset,
            covariance,
            status: FixStatus::Single,
        });
    }
    GnssFixes::from_fixes(fixes, TimeBase::Source)
}

/// Reads an NMEA 0183 log (format in the module doc).
pub fn read_nmea(path: impl AsRef<Path>, geoid_offset: f64) -> Result<GnssFixes> {
    let path = path.as_ref();
    parse_nmea(open(path)?, path, geoid_offset)
}

/// A GGA fix before its date and accuracy are known.
struct Gga {
    day: u32,
    tod: f64,
    fix: GnssFix,
}

/// Days from 1970-01-01 to a civil date (H. Hinnant's `days_from_civil`).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The key of an epoch: day index and time of day in milliseconds.
fn epoch_key(day: u32, tod: f64) -> (u32, i64) {
    (day, (tod * 1000.0).round() as i64)
}

/// Checks the `*hh` checksum of a sentence starting at `$` and returns its
/// fields (without `$` and the checksum).
fn checked_fields<'a>(sentence: &'a str, lines: &Lines<impl BufRead>) -> Result<Vec<&'a str>> {
    let Some(star) = sentence.rfind('*') else {
        return Err(lines.err(format!(
            "NMEA sentence without a checksum (*hh): {sentence:?}"
        )));
    };
    let body = &sentence[1..star];
    let given = sentence[star + 1..].trim();
    let given = u8::from_str_radix(given, 16)
        .ok()
        .filter(|_| given.len() == 2)
        .ok_or_else(|| lines.err(format!("NMEA checksum {given:?} is not two hex digits")))?;
    let computed = body.bytes().fold(0u8, |a, b| a ^ b);
    if computed != given {
        return Err(lines.err(format!(
            "NMEA checksum mismatch: the sentence says {given:02X}, its characters give {computed:02X}"
        )));
    }
    Ok(body.split(',').collect())
}

/// `hhmmss.sss` to seconds of the day.
fn time_of_day(s: &str) -> Option<f64> {
    if s.len() < 6 || !s.is_char_boundary(2) || !s.is_char_boundary(4) {
        return None;
    }
    let h: u32 = s[0..2].parse().ok()?;
    let m: u32 = s[2..4].parse().ok()?;
    let sec: f64 = s[4..].parse().ok()?;
    (h < 24 && m < 60 && (0.0..61.0).contains(&sec)).then(|| (h * 3600 + m * 60) as f64 + sec)
}

/// `ddmm.mmmm` / `dddmm.mmmm` and a hemisphere letter to signed degrees.
fn angle(value: &str, hemi: &str, pos: char, neg: char) -> Option<f64> {
    let v: f64 = value.parse().ok()?;
    if !v.is_finite() || v < 0.0 {
        return None;
    }
    let deg = (v / 100.0).floor();
    let min = v - deg * 100.0;
    if min >= 60.0 {
        return None;
    }
    let a = deg + min / 60.0;
    match hemi.chars().next() {
        Some(c) if c == pos => Some(a),
        Some(c) if c == neg => Some(-a),
        _ => None,
    }
}

fn field<'a>(f: &[&'a str], i: usize) -> &'a str {
    f.get(i).copied().unwrap_or("")
}

/// [`read_nmea`] from any reader; `path` names the source in errors.
pub fn parse_nmea(reader: impl BufRead, path: &Path, geoid_offset: f64) -> Result<GnssFixes> {
    let mut lines = Lines::new(reader, path);
    let mut ggas: Vec<Gga> = Vec::new();
    let mut sigmas: HashMap<(u32, i64), [f64; 3]> = HashMap::new();
    // (day index, days since 1970) of the first date seen.
    let mut date: Option<(u32, i64)> = None;
    let mut day = 0u32;
    let mut last_tod: Option<f64> = None;
    while let Some(line) = lines.next_line()? {
        let Some(start) = line.find('$') else {
            continue;
        };
        let sentence = line[start..].trim_end();
        let f = checked_fields(sentence, &lines)?;
        let name = f[0];
        // Talker (2 letters, `P` + maker for proprietary ones) then the type.
        let Some(kind) = name.len().checked_sub(3).and_then(|k| name.get(k..)) else {
            continue;
        };
        if !matches!(kind, "GGA" | "GST" | "RMC" | "ZDA") {
            continue;
        }
        let tod_field = field(&f, 1);
        let tod = match time_of_day(tod_field) {
            Some(t) => t,
            None if kind == "GGA" && field(&f, 6) == "0" => {
                // No fix and no time: counted, nothing else to read.
                ggas.push(Gga {
                    day,
                    tod: f64::NAN,
                    fix: GnssFix {
                        time: f64::NAN,
                        lat: f64::NAN,
                        lon: f64::NAN,
                        alt: f64::NAN,
                        covariance: None,
                        status: FixStatus::NoFix,
                    },
                });
                continue;
            }
            None => return Err(lines.err(format!("{name}: time {tod_field:?} is not hhmmss.ss"))),
        };
        if let Some(prev) = last_tod {
            if tod + 43_200.0 < prev {
                day += 1; // past midnight
            }
        }
        last_tod = Some(tod);
        match kind {
            "GGA" => {
                let q = field(&f, 6);
                let quality: u8 = q
                    .parse()
                    .map_err(|_| lines.err(format!("GGA fix quality {q:?} is not a number")))?;
                let status = FixStatus::from_gga_quality(quality);
                let (lat, lon, alt) = if status.is_fix() {
                    let lat = angle(field(&f, 2), field(&f, 3), 'N', 'S').ok_or_else(|| {
                        lines.err(format!(
                            "GGA latitude {:?} {:?} is not ddmm.mmmm N/S",
                            field(&f, 2),
                            field(&f, 3)
                        ))
                    })?;
                    let lon = angle(field(&f, 4), field(&f, 5), 'E', 'W').ok_or_else(|| {
                        lines.err(format!(
                            "GGA longitude {:?} {:?} is not dddmm.mmmm E/W",
                            field(&f, 4),
                            field(&f, 5)
                        ))
                    })?;
                    let alt: f64 = field(&f, 9).parse().map_err(|_| {
                        lines.err(format!("GGA altitude {:?} is not a number", field(&f, 9)))
                    })?;
                    let sep = match field(&f, 11) {
                        "" => geoid_offset,
                        s => s.parse::<f64>().map_err(|_| {
                            lines.err(format!("GGA geoid separation {s:?} is not a number"))
                        })?,
                    };
                    (lat, lon, alt + sep)
                } else {
                    (f64::NAN, f64::NAN, f64::NAN)
                };
                ggas.push(Gga {
                    day,
                    tod,
                    fix: GnssFix {
                        time: tod,
                        lat,
                        lon,
                        alt,
                        covariance: None,
                        status,
                    },
                });
            }
            "GST" => {
                let sd: Vec<Option<f64>> = (6..9).map(|i| field(&f, i).parse().ok()).collect();
                if let [Some(lat), Some(lon), Some(alt)] = sd[..] {
                    sigmas.insert(epoch_key(day, tod), [lon, lat, alt]);
                }
            }
            "RMC" if date.is_none() => {
                let d = field(&f, 9);
                if d.len() == 6 && d.bytes().all(|b| b.is_ascii_digit()) {
                    let dd: i64 = d[0..2].parse().unwrap_or(0);
                    let mm: i64 = d[2..4].parse().unwrap_or(0);
                    let yy: i64 = d[4..6].parse().unwrap_or(0);
                    let year = if yy < 80 { 2000 + yy } else { 1900 + yy };
                    if (1..=31).contains(&dd) && (1..=12).contains(&mm) {
                        date = Some((day, days_from_civil(year, mm, dd)));
                    }
                }
            }
            "ZDA" if date.is_none() => {
                let dd: Option<i64> = field(&f, 2).parse().ok();
                let mm: Option<i64> = field(&f, 3).parse().ok();
                let yyyy: Option<i64> = field(&f, 4).parse().ok();
                if let (Some(dd), Some(mm), Some(y)) = (dd, mm, yyyy) {
                    if (1..=31).contains(&dd) && (1..=12).contains(&mm) && y > 1970 {
                        date = Some((day, days_from_civil(y, mm, dd)));
                    }
                }
            }
            _ => {}
        }
    }
    let (time_base, day0) = match date {
        Some((at_day, days)) => (TimeBase::Source, Some(days - at_day as i64)),
        None => (TimeBase::TimeOfDay, None),
    };
    let fixes = ggas.into_iter().map(|g| {
        let mut fix = g.fix;
        if fix.status.is_fix() {
            let base = day0.unwrap_or(0) + g.day as i64;
            fix.time = base as f64 * 86_400.0 + g.tod;
            fix.covariance = sigmas
                .get(&epoch_key(g.day, g.tod))
                .filter(|s| s.iter().all(|&v| v > 0.0 && v.is_finite()))
                .map(|s| {
                    Matrix3::from_diagonal(&Vector3::new(s[0] * s[0], s[1] * s[1], s[2] * s[2]))
                });
        }
        fix
    });
    let out = GnssFixes::from_fixes(fixes, time_base)?;
    if out.is_empty() && out.dropped_no_fix == 0 {
        return Err(Error::parse(path, 0, "no GGA sentence in the file"));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn with_checksum(body: &str) -> String {
        let c = body.bytes().fold(0u8, |a, b| a ^ b);
        format!("${body}*{c:02X}")
    }

    #[test]
    fn fixes_are_told_from_trajectories_by_their_rows() {
        let dir = tempfile::tempdir().unwrap();
        let sniff = |name: &str, text: &str| {
            let p = dir.path().join(name);
            std::fs::write(&p, text).unwrap();
            GnssFormat::sniff_text(&p).unwrap()
        };
        let gga =
            with_checksum("GPGGA,124637.60,4811.5214,N,01137.1672,E,4,12,0.6,494.6,M,47.5,M,,");
        assert_eq!(sniff("a.nmea", &format!("{gga}\n")), Some(GnssFormat::Nmea));
        assert_eq!(
            sniff("a.csv", "time,lat,lon,alt\n1.0,48.1,11.5,520\n"),
            Some(GnssFormat::Csv)
        );
        assert_eq!(
            sniff("b.csv", "# fixes\n1.0 48.1 11.5 520 1 1 4\n"),
            Some(GnssFormat::Csv)
        );
        // TUM and EuRoC rows, and four columns that are no latitude and longitude.
        assert_eq!(
            sniff("tum.txt", "# t x y z qx qy qz qw\n1 48 11 5 0 0 0 1\n"),
            None
        );
        let euroc = format!("#timestamp,x\n1403636579758555392{}\n", ",0.5".repeat(16));
        assert_eq!(sniff("gt.csv", &euroc), None);
        assert_eq!(sniff("xyz.txt", "1.0 120.5 -300.2 4\n"), None);
        assert_eq!(sniff("empty.txt", "# nothing\n"), None);
    }

    #[test]
    fn civil_days() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(days_from_civil(2020, 10, 7), 18_542);
        assert_eq!(days_from_civil(2000, 3, 1), 11_017);
    }

    #[test]
    fn gga_without_date_counts_from_midnight_and_rolls_over() {
        let text = [
            with_checksum("GPGGA,235959.00,4811.0000,N,01137.0000,E,1,08,1.0,500.0,M,47.5,M,,"),
            with_checksum("GPGGA,000001.00,4811.0100,N,01137.0000,E,1,08,1.0,500.0,M,47.5,M,,"),
        ]
        .join("\n");
        let f = parse_nmea(text.as_bytes(), Path::new("t.nmea"), 0.0).unwrap();
        assert_eq!(f.time_base, TimeBase::TimeOfDay);
        assert_eq!(f.times, vec![86_399.0, 86_401.0]);
        assert!((f.lat[0] - (48.0 + 11.0 / 60.0)).abs() < 1e-12);
        assert!((f.alt[0] - 547.5).abs() < 1e-12);
    }

    #[test]
    fn long_lines_are_refused() {
        let zeros = vec![0u8; MAX_LINE * 3];
        let e = parse_nmea(&zeros[..], Path::new("zero"), 0.0).unwrap_err();
        assert!(matches!(e, Error::Parse { line: 1, .. }), "{e}");
        let e = parse_gnss_csv(&zeros[..], Path::new("zero"), 0.0).unwrap_err();
        assert!(e.to_string().contains("longer than"), "{e}");
    }
}
