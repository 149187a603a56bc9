//! Live in Foxglove: the metric world served on a Foxglove WebSocket
//! (the official `foxglove` SDK crate's server, protocol `foxglove.sdk.v1`),
//! so that Foxglove's 3-D panel shows it without a file being opened.
//!
//! - [`WorldServer`]: a finished conversion's `world.mcap` (`slam2world
//!   serve OUT/`, Python `slam2world.serve`): every channel of the file is
//!   advertised with its topic, encoding and schema, and a client that
//!   subscribes to one gets that channel's messages, in the file's order and
//!   with their log times (a late client gets them too: the world is
//!   latched). A layout made for the file works on the server as it is.
//! - [`WsSource`]: the input side, a client of a running Foxglove WebSocket
//!   server (the SDK's, `foxglove_bridge`'s) whose SLAM, reference and IMU
//!   channels `follow ws://HOST:PORT` reads as it reads a growing log.
//!
//! The server binds `127.0.0.1` unless another address is named. Messages go
//! to each client through its own bounded queue in the SDK (the oldest
//! dropped for a client that lags), so that a slow client never holds up
//! the others.

/// The Foxglove layout of the world (`layout.json`, made by `layout.py`
/// with the Foxglove SDK's layout API): a 3-D panel in the `world` frame with
/// the cloud, the paths, the voxels and the grid, the session's state and a
/// plot of its fit and latency. It fits `world.mcap` and every server alike
/// (`slam2world layout` writes it; Foxglove: Layouts, Import from file).
pub const FOXGLOVE_LAYOUT: &str = include_str!("layout.json");

mod cloud;
mod world_server;
mod ws_source;

pub use cloud::LiveCloud;

pub use world_server::{ServeOptions, WorldServer};
pub use ws_source::{WsChannel, WsMessage, WsSource, SUBPROTOCOLS};
