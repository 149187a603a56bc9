//! [`read_gnss_mcap`], the fixes of one GNSS topic of an MCAP log; the
//! decoders themselves (`sensor_msgs/NavSatFix`, `foxglove.LocationFix`) are
//! [`crate::io::messages::gnss`], re-exported here.

use std::path::Path;

use super::decode::MessageKind;
use super::reader::{ChannelInfo, McapFile};
use crate::error::{Error, Result};
use crate::geo::{GnssFixes, TimeBase};
pub use crate::io::messages::gnss::*;

fn is_gnss(c: &ChannelInfo) -> bool {
    matches!(
        MessageKind::from_schema(&c.schema_name),
        Some(MessageKind::NavSatFix | MessageKind::LocationFix)
    )
}

/// The GNSS fixes of an MCAP log: the topic named, or the only
/// `NavSatFix` / `LocationFix` topic. Fixes in log-file order; their times
/// are the message stamps ([`TimeBase::Source`]).
///
/// Errors ([`Error::Mcap`]): no GNSS topic, several and none named, a named
/// topic missing or of another schema, a message that does not decode (with
/// its index); the fixes' own checks as in [`GnssFixes::from_fixes`].
pub fn read_gnss_mcap(path: impl AsRef<Path>, topic: Option<&str>) -> Result<GnssFixes> {
    let path = path.as_ref();
    let err = |reason: String| Error::Mcap {
        path: path.to_path_buf(),
        reason,
    };
    let file = McapFile::open(path)?;
    let channels = file.channels()?;
    let chosen: Vec<&ChannelInfo> = match topic {
        Some(t) => {
            let c: Vec<&ChannelInfo> = channels.values().filter(|c| c.topic == t).collect();
            if c.is_empty() {
                return Err(err(format!("no topic {t:?} in the log")));
            }
            if let Some(bad) = c.iter().find(|c| !is_gnss(c)) {
                return Err(err(format!(
                    "topic {t:?} has schema {:?}, not sensor_msgs/NavSatFix or foxglove.LocationFix",
                    bad.schema_name
                )));
            }
            c
        }
        None => {
            let c: Vec<&ChannelInfo> = channels.values().filter(|c| is_gnss(c)).collect();
            let mut topics: Vec<&str> = c.iter().map(|c| c.topic.as_str()).collect();
            topics.sort_unstable();
            topics.dedup();
            match topics.len() {
                0 => {
                    return Err(err(
                        "no sensor_msgs/NavSatFix or foxglove.LocationFix topic in the log".into(),
                    ))
                }
                1 => c,
                _ => {
                    return Err(err(format!(
                        "several GNSS topics ({}): name one",
                        topics.join(", ")
                    )))
                }
            }
        }
    };
    let ids: Vec<u16> = chosen.iter().map(|c| c.id).collect();
    let scan = file.scan(|c| ids.contains(&c.id))?;
    let mut fixes = Vec::with_capacity(scan.len());
    for (i, m) in scan.iter().enumerate() {
        let Some(c) = scan.channels.get(&m.channel_id) else {
            continue;
        };
        let kind = MessageKind::from_schema(&c.schema_name).ok_or_else(|| {
            err(format!(
                "topic {}: schema {:?} is not GNSS",
                c.topic, c.schema_name
            ))
        })?;
        let fix = gnss_fix(kind, &c.message_encoding, m.data).map_err(|e| {
            err(format!(
                "topic {}: message {i} (log time {} ns): {e}",
                c.topic, m.log_time
            ))
        })?;
        fixes.push(fix);
    }
    GnssFixes::from_fixes(fixes, TimeBase::Source)
}
