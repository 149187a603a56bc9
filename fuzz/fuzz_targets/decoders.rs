//! Every message decoder on arbitrary bytes: errors are fine, panics are not.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slam2world::io::mcap::decode::{self, MessageKind};

const KINDS: [MessageKind; 7] = [
    MessageKind::PoseStamped,
    MessageKind::PoseWithCovarianceStamped,
    MessageKind::Odometry,
    MessageKind::PoseInFrame,
    MessageKind::PosesInFrame,
    MessageKind::Tf,
    MessageKind::Imu,
];
const ENCODINGS: [&str; 4] = ["ros1", "cdr", "protobuf", "json"];

fuzz_target!(|data: &[u8]| {
    let Some((&sel, body)) = data.split_first() else {
        return;
    };
    let kind = KINDS[sel as usize % KINDS.len()];
    let encoding = ENCODINGS[(sel as usize / KINDS.len()) % ENCODINGS.len()];
    let _ = decode::poses(kind, encoding, body);
    let _ = decode::pose_sample(kind, encoding, body);
    let _ = decode::imu(encoding, body);
    if let Ok(k) = decode::keyframe_ros1(body) {
        let _ = decode::split_pointcloud(k.pointcloud);
    }
    let _ = decode::graph_ros1(body);
});
