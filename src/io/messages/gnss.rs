//! GNSS message decoders: `sensor_msgs/NavSatFix` (ROS 1 and ROS 2 CDR) and
//! `foxglove.LocationFix` (protobuf and JSON), for every container.
//!
//! Both messages carry latitude and longitude in degrees, altitude in metres
//! above the WGS84 ellipsoid, and `position_covariance`: row-major 3×3 in m²,
//! in ENU at the fix (x east, y north, z up), with a type saying how much of it
//! is known (0 unknown, 1 approximated, 2 diagonal known, 3 known).
//!
//! Decoders return a [`WireError`] saying what was wrong, like the other
//! decoders; the readers add the file, topic and message index.

use nalgebra::Matrix3;
use serde::Deserialize;

use super::decode::{pb_time, MessageKind};
use super::wire::{pb_fields, Cdr, PbValue, Ros1, RosReader, WireError, WireResult};
use crate::geo::{FixStatus, GnssFix};

/// `position_covariance_type` value meaning the covariance is unknown.
pub const COVARIANCE_TYPE_UNKNOWN: u8 = 0;

/// A decoded `sensor_msgs/NavSatFix`.
#[derive(Clone, Debug, PartialEq)]
pub struct NavSatFixMsg {
    /// Header stamp, seconds.
    pub time: f64,
    /// Header frame (the antenna).
    pub frame_id: String,
    /// `NavSatStatus.status`: -1 no fix, 0 fix, 1 SBAS, 2 GBAS.
    pub status: i8,
    /// `NavSatStatus.service` bit mask (1 GPS, 2 GLONASS, 4 COMPASS, 8 GALILEO).
    pub service: u16,
    /// Degrees north.
    pub latitude: f64,
    /// Degrees east.
    pub longitude: f64,
    /// Metres above the WGS84 ellipsoid.
    pub altitude: f64,
    /// Row-major ENU covariance, m².
    pub position_covariance: [f64; 9],
    /// 0 unknown, 1 approximated, 2 diagonal known, 3 known.
    pub covariance_type: u8,
}

/// A decoded `foxglove.LocationFix` (it has no fix status).
#[derive(Clone, Debug, PartialEq)]
pub struct LocationFixMsg {
    /// `timestamp`, seconds.
    pub time: f64,
    /// Frame of the sensor.
    pub frame_id: String,
    /// Degrees north.
    pub latitude: f64,
    /// Degrees east.
    pub longitude: f64,
    /// Metres above the WGS84 ellipsoid.
    pub altitude: f64,
    /// Row-major ENU covariance, m² (zeros when absent).
    pub position_covariance: [f64; 9],
    /// 0 unknown, 1 approximated, 2 diagonal known, 3 known.
    pub covariance_type: u8,
}

fn covariance(c: &[f64; 9], kind: u8) -> Option<Matrix3<f64>> {
    (kind != COVARIANCE_TYPE_UNKNOWN).then(|| Matrix3::from_row_slice(c))
}

impl NavSatFixMsg {
    /// The fix for [`GnssFixes`] (covariance only when its type is not unknown).
    pub fn to_fix(&self) -> GnssFix {
        GnssFix {
            time: self.time,
            lat: self.latitude,
            lon: self.longitude,
            alt: self.altitude,
            covariance: covariance(&self.position_covariance, self.covariance_type),
            status: FixStatus::from_navsat_status(self.status),
        }
    }
}

impl LocationFixMsg {
    /// The fix for [`GnssFixes`] (status [`FixStatus::Single`]: the message has none).
    pub fn to_fix(&self) -> GnssFix {
        GnssFix {
            time: self.time,
            lat: self.latitude,
            lon: self.longitude,
            alt: self.altitude,
            covariance: covariance(&self.position_covariance, self.covariance_type),
            status: FixStatus::Single,
        }
    }
}

/// Decodes `sensor_msgs/NavSatFix` in `ros1` or `cdr`.
pub fn navsatfix(encoding: &str, data: &[u8]) -> WireResult<NavSatFixMsg> {
    match encoding {
        "ros1" => navsatfix_fields(&mut Ros1::new(data)),
        "cdr" => navsatfix_fields(&mut Cdr::new(data)?),
        other => Err(WireError::schema(format!(
            "sensor_msgs/NavSatFix in encoding {other:?} is not supported (ros1 or cdr)"
        ))),
    }
}

/// The fields of a NavSatFix, in either ROS encoding (the reader aligns and
/// orders the bytes).
fn navsatfix_fields<'a>(r: &mut impl RosReader<'a>) -> WireResult<NavSatFixMsg> {
    let (time, frame_id) = r.header()?;
    let status = r.u8()? as i8;
    let service = r.u16()?;
    let (latitude, longitude, altitude) = (r.f64()?, r.f64()?, r.f64()?);
    let mut position_covariance = [0.0; 9];
    for v in &mut position_covariance {
        *v = r.f64()?;
    }
    let covariance_type = r.u8()?;
    Ok(NavSatFixMsg {
        time,
        frame_id,
        status,
        service,
        latitude,
        longitude,
        altitude,
        position_covariance,
        covariance_type,
    })
}

/// `foxglove.LocationFix` in protobuf: latitude 1, longitude 2, altitude 3
/// (double), position_covariance 4 (repeated double, packed or not),
/// position_covariance_type 5 (enum), timestamp 6, frame_id 7.
fn location_fix_protobuf(data: &[u8]) -> WireResult<LocationFixMsg> {
    let mut m = LocationFixMsg {
        time: 0.0,
        frame_id: String::new(),
        latitude: 0.0,
        longitude: 0.0,
        altitude: 0.0,
        position_covariance: [0.0; 9],
        covariance_type: 0,
    };
    let mut cov: Vec<f64> = Vec::new();
    for f in pb_fields(data) {
        match f? {
            (1, v) => m.latitude = v.as_f64()?,
            (2, v) => m.longitude = v.as_f64()?,
            (3, v) => m.altitude = v.as_f64()?,
            (4, PbValue::Bytes(b)) => {
                if b.len() % 8 != 0 || cov.len() + b.len() / 8 > 9 {
                    return Err(WireError::schema(format!(
                        "position_covariance: {} packed bytes, expected 9 doubles in all",
                        b.len()
                    )));
                }
                cov.extend(
                    b.chunks_exact(8).map(|c| {
                        f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]])
                    }),
                );
            }
            (4, v) => {
                if cov.len() == 9 {
                    return Err(WireError::schema("position_covariance: more than 9 values"));
                }
                cov.push(v.as_f64()?);
            }
            (5, v) => {
                let t = v.as_u64()?;
                m.covariance_type = u8::try_from(t).ok().filter(|t| *t <= 3).ok_or_else(|| {
                    WireError::value(format!("position_covariance_type {t}: expected 0 to 3"))
                })?;
            }
            (6, v) => m.time = pb_time(v.as_bytes()?)?,
            (7, v) => m.frame_id = String::from_utf8_lossy(v.as_bytes()?).into_owned(),
            _ => {}
        }
    }
    set_covariance(&mut m.position_covariance, &cov, m.covariance_type)?;
    Ok(m)
}

fn set_covariance(out: &mut [f64; 9], cov: &[f64], kind: u8) -> WireResult<()> {
    match cov.len() {
        9 => out.copy_from_slice(cov),
        0 if kind == COVARIANCE_TYPE_UNKNOWN => {}
        n => {
            return Err(WireError::schema(format!(
                "position_covariance has {n} values, expected 9 (type {kind})"
            )))
        }
    }
    Ok(())
}

#[derive(Deserialize)]
struct JsonTime {
    #[serde(default)]
    sec: i64,
    #[serde(default)]
    nsec: i64,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum JsonCovType {
    Number(u8),
    Name(String),
}

#[derive(Deserialize)]
struct JsonLocationFix {
    timestamp: Option<JsonTime>,
    #[serde(default)]
    frame_id: String,
    latitude: f64,
    longitude: f64,
    altitude: f64,
    #[serde(default)]
    position_covariance: Vec<f64>,
    position_covariance_type: Option<JsonCovType>,
}

fn location_fix_json(data: &[u8]) -> WireResult<LocationFixMsg> {
    let j: JsonLocationFix = serde_json::from_slice(data)
        .map_err(|e| WireError::schema(format!("LocationFix JSON: {e}")))?;
    let covariance_type = match j.position_covariance_type {
        None => 0,
        Some(JsonCovType::Number(n)) if n <= 3 => n,
        Some(JsonCovType::Number(n)) => {
            return Err(WireError::schema(format!(
                "position_covariance_type {n}: expected 0 to 3"
            )))
        }
        Some(JsonCovType::Name(s)) => match s.as_str() {
            "UNKNOWN" => 0,
            "APPROXIMATED" => 1,
            "DIAGONAL_KNOWN" => 2,
            "KNOWN" => 3,
            other => {
                return Err(WireError::schema(format!(
                    "position_covariance_type {other:?} is not a known name"
                )))
            }
        },
    };
    let mut position_covariance = [0.0; 9];
    set_covariance(
        &mut position_covariance,
        &j.position_covariance,
        covariance_type,
    )?;
    let time = j
        .timestamp
        .map_or(0.0, |t| t.sec as f64 + t.nsec as f64 * 1e-9);
    Ok(LocationFixMsg {
        time,
        frame_id: j.frame_id,
        latitude: j.latitude,
        longitude: j.longitude,
        altitude: j.altitude,
        position_covariance,
        covariance_type,
    })
}

/// Decodes `foxglove.LocationFix` in `protobuf` or `json`.
pub fn location_fix(encoding: &str, data: &[u8]) -> WireResult<LocationFixMsg> {
    match encoding {
        "protobuf" => location_fix_protobuf(data),
        "json" => location_fix_json(data),
        other => Err(WireError::schema(format!(
            "foxglove.LocationFix in encoding {other:?} is not supported (protobuf or json)"
        ))),
    }
}

/// The fix of one message of a GNSS kind.
pub fn gnss_fix(kind: MessageKind, encoding: &str, data: &[u8]) -> WireResult<GnssFix> {
    match kind {
        MessageKind::NavSatFix => navsatfix(encoding, data).map(|m| m.to_fix()),
        MessageKind::LocationFix => location_fix(encoding, data).map(|m| m.to_fix()),
        other => Err(WireError::schema(format!(
            "{other:?} is not a GNSS message"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::messages::wire::PbWriter;

    fn ros1_navsatfix(status: i8, cov_type: u8) -> Vec<u8> {
        let mut m = Vec::new();
        m.extend_from_slice(&7u32.to_le_bytes()); // seq
        m.extend_from_slice(&100u32.to_le_bytes());
        m.extend_from_slice(&500_000_000u32.to_le_bytes());
        m.extend_from_slice(&4u32.to_le_bytes());
        m.extend_from_slice(b"/gps");
        m.push(status as u8);
        m.extend_from_slice(&1u16.to_le_bytes());
        for v in [
            42.5, -71.1, 12.0, 0.81, 0.0, 0.0, 0.0, 0.81, 0.0, 0.0, 0.0, 3.24,
        ] {
            m.extend_from_slice(&f64::to_le_bytes(v));
        }
        m.push(cov_type);
        m
    }

    #[test]
    fn navsatfix_ros1() {
        let m = navsatfix("ros1", &ros1_navsatfix(1, 1)).unwrap();
        assert_eq!(m.time, 100.5);
        assert_eq!(m.frame_id, "/gps");
        assert_eq!((m.status, m.service), (1, 1));
        assert_eq!((m.latitude, m.longitude, m.altitude), (42.5, -71.1, 12.0));
        let f = m.to_fix();
        assert_eq!(f.status, FixStatus::Differential);
        assert_eq!(f.covariance.unwrap()[(2, 2)], 3.24);
        assert!(navsatfix("ros1", &ros1_navsatfix(0, 0))
            .unwrap()
            .to_fix()
            .covariance
            .is_none());
        assert_eq!(
            navsatfix("ros1", &ros1_navsatfix(-1, 0))
                .unwrap()
                .to_fix()
                .status,
            FixStatus::NoFix
        );
        let full = ros1_navsatfix(0, 2);
        for cut in [3, 20, full.len() - 1] {
            assert!(navsatfix("ros1", &full[..cut]).is_err(), "cut at {cut}");
        }
        assert!(navsatfix("json", &full).is_err());
    }

    #[test]
    fn location_fix_protobuf_packed_and_json() {
        let mut ts = PbWriter::new();
        ts.int(1, 3);
        ts.int(2, 250_000_000);
        let mut w = PbWriter::new();
        w.message(6, &ts);
        w.bytes(7, b"antenna");
        w.double(1, 48.1);
        w.double(2, 11.6);
        w.double(3, 540.0);
        let cov: Vec<u8> = [4.0, 0.0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0, 9.0]
            .iter()
            .flat_map(|v: &f64| v.to_le_bytes())
            .collect();
        w.bytes(4, &cov);
        w.int(5, 2);
        let m = location_fix("protobuf", &w.buf).unwrap();
        assert_eq!(m.time, 3.25);
        assert_eq!(m.frame_id, "antenna");
        assert_eq!(m.position_covariance[8], 9.0);
        assert_eq!(m.covariance_type, 2);
        let j = br#"{"timestamp":{"sec":3,"nsec":250000000},"frame_id":"antenna",
            "latitude":48.1,"longitude":11.6,"altitude":540.0,
            "position_covariance":[4,0,0,0,4,0,0,0,9],"position_covariance_type":2}"#;
        assert_eq!(location_fix("json", j).unwrap(), m);
        let bad = br#"{"latitude":48.1,"longitude":11.6,"altitude":1,"position_covariance":[1,2],"position_covariance_type":3}"#;
        assert!(location_fix("json", bad).is_err());
        let mut short = PbWriter::new();
        short.bytes(4, &cov[..16]);
        short.int(5, 3);
        assert!(location_fix("protobuf", &short.buf).is_err());
    }
}
