//! [`WorldServer`]: a finished conversion's `world.mcap` on a Foxglove
//! WebSocket.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{mpsc, Arc, Mutex};
use std::thread::JoinHandle;

use foxglove::websocket::{ChannelView, Client, ServerListener};
use foxglove::{
    ChannelBuilder, ChannelId, Context, PartialMetadata, RawChannel, Schema, SinkId,
    WebSocketServer, WebSocketServerHandle,
};

use crate::error::{Error, Result};
use crate::io::mcap::McapFile;

/// Where [`WorldServer`] listens.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ServeOptions {
    /// Address to bind: `127.0.0.1` (this machine only, the default), or
    /// another (`0.0.0.0`: every interface) named on purpose.
    pub host: String,
    /// Port; 0 takes a free one ([`WorldServer::port`] says which).
    pub port: u16,
}

impl Default for ServeOptions {
    /// `127.0.0.1:8765`, Foxglove's default port.
    fn default() -> Self {
        ServeOptions {
            host: "127.0.0.1".into(),
            port: 8765,
        }
    }
}

impl std::str::FromStr for ServeOptions {
    type Err = Error;

    /// `PORT` (on `127.0.0.1`) or `HOST:PORT`.
    fn from_str(s: &str) -> Result<Self> {
        let t = s.trim();
        let (host, port) = match t.rsplit_once(':') {
            Some((h, p)) => (h.trim_start_matches('[').trim_end_matches(']'), p),
            None => ("127.0.0.1", t),
        };
        let port = port.parse::<u16>().map_err(|_| {
            Error::invalid(
                "serve",
                format!("expected PORT or HOST:PORT (a port 0..65535), got {t:?}"),
            )
        })?;
        if host.is_empty() {
            return Err(Error::invalid(
                "serve",
                format!("expected PORT or HOST:PORT, got {t:?}"),
            ));
        }
        Ok(ServeOptions {
            host: host.to_string(),
            port,
        })
    }
}

/// Messages queued for one client of a live world ([`WorldServer::live`])
/// before the oldest are dropped: about six worlds of ten messages. The
/// bound is in messages: a client that subscribed to the cloud alone and
/// reads nothing holds up to this many clouds (8 MB each at the default
/// bound).
const LIVE_BACKLOG: usize = 64;

/// How long [`WorldServer::stop`] waits for its clients' sends to end.
const STOP_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

/// What the listener and the owner ask of the worker.
enum Request {
    /// Send channel `channel`'s messages to client `sink`.
    Send { sink: SinkId, channel: ChannelId },
    /// The world as it now stands (an MCAP in memory): send it to every
    /// subscriber.
    Publish(Arc<Vec<u8>>),
    /// The server stops.
    Stop,
}

/// Hands each subscription to the worker (a listener must not block the
/// client's poll loop).
struct Listener {
    tx: Mutex<mpsc::Sender<Request>>,
}

impl ServerListener for Listener {
    fn on_subscribe(&self, client: Client, channel: ChannelView) {
        if let Some(sink) = client.sink_id() {
            let tx = self.tx.lock().unwrap_or_else(|e| e.into_inner());
            // The worker is gone only once the server stops.
            let _ = tx.send(Request::Send {
                sink,
                channel: channel.id(),
            });
        }
    }
}

/// The file as served: what the worker reads and sends.
struct Served {
    path: PathBuf,
    context: Arc<Context>,
    file: Option<McapFile>,
    /// By topic: the channel's id in the file as last read (`None`: not in
    /// it), and the SDK's channel.
    channels: HashMap<String, (Option<u16>, Arc<RawChannel>)>,
    /// The SDK's channel ids to topics.
    topics_by_id: HashMap<ChannelId, String>,
    /// The topics, in the order they were first served (shared with the owner).
    topics: Arc<Mutex<Vec<String>>>,
}

impl Served {
    /// Reads the file, advertising its topics.
    fn load(&mut self) -> Result<()> {
        let file = McapFile::open(&self.path)?;
        self.adopt(file)
    }

    /// Serves `file` from now on, advertising the topics it has that were
    /// not served before. The channels keep their topic's first encoding
    /// and schema.
    fn adopt(&mut self, file: McapFile) -> Result<()> {
        let infos = file.channels()?;
        // The new topics' channels first; the served world changes only
        // once all of them are there.
        for info in infos.values() {
            if self.channels.contains_key(&info.topic) {
                continue;
            }
            let schema = (info.schema_id != 0).then(|| {
                Schema::new(
                    info.schema_name.clone(),
                    info.schema_encoding.clone(),
                    info.schema_data.clone(),
                )
            });
            let channel = ChannelBuilder::new(info.topic.clone())
                .context(&self.context)
                .message_encoding(info.message_encoding.clone())
                .schema(schema)
                .metadata(info.metadata.clone())
                .build_raw()
                .map_err(|e| Error::Mcap {
                    path: self.path.clone(),
                    reason: format!("channel {}: {e}", info.topic),
                })?;
            self.topics_by_id.insert(channel.id(), info.topic.clone());
            self.channels.insert(info.topic.clone(), (None, channel));
            self.topics
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push(info.topic.clone());
        }
        for c in self.channels.values_mut() {
            c.0 = None;
        }
        for info in infos.values() {
            if let Some(c) = self.channels.get_mut(&info.topic) {
                c.0 = Some(info.id);
            }
        }
        self.file = Some(file);
        Ok(())
    }

    /// Sends the messages of the file as last read, on the topics `want`
    /// accepts that have subscribers, to `sink` (`None`: every subscriber):
    /// one pass over the file, in its order.
    fn send(&self, want: impl Fn(&str) -> bool, sink: Option<SinkId>) {
        let Some(file) = &self.file else {
            return;
        };
        let out: HashMap<u16, &Arc<RawChannel>> = self
            .channels
            .iter()
            .filter(|(topic, (_, c))| want(topic) && c.has_sinks())
            .filter_map(|(_, (id, c))| id.map(|i| (i, c)))
            .collect();
        if out.is_empty() {
            return;
        }
        // A file that shrank since it was read sends nothing more.
        let Ok(scan) = file.scan(|c| out.contains_key(&c.id)) else {
            return;
        };
        for m in scan.iter() {
            if let Some(c) = out.get(&m.channel_id) {
                c.log_with_meta_to_sink(
                    m.data,
                    PartialMetadata {
                        log_time: Some(m.log_time),
                    },
                    sink,
                );
            }
        }
    }

    /// Sends channel `channel` (the SDK's id) to the client `sink` that
    /// subscribed to it.
    fn send_subscribed(&self, sink: SinkId, channel: ChannelId) {
        if let Some(topic) = self.topics_by_id.get(&channel) {
            self.send(|t| t == topic, Some(sink));
        }
    }
}

/// A conversion's `world.mcap` served on a Foxglove WebSocket: each channel
/// of the file advertised as it is (topic, message encoding, schema,
/// metadata), and its messages sent, in the file's order and with their log
/// times, to each client that subscribes (when it subscribes: the world is
/// latched for late clients). The file is read again per subscription (that
/// channel's chunks only), never held whole. [`WorldServer::live`] serves
/// the world of a running conversion (`follow --serve`, `Session.serve`):
/// each version handed to [`WorldServer::publish`] in memory goes to every
/// subscriber at once, the topics it gained advertised, and is kept for
/// the clients that subscribe later. Stops on [`WorldServer::stop`] or when
/// dropped.
pub struct WorldServer {
    path: PathBuf,
    host: String,
    port: u16,
    topics: Arc<Mutex<Vec<String>>>,
    handle: Option<WebSocketServerHandle>,
    worker: Option<JoinHandle<()>>,
    tx: mpsc::Sender<Request>,
    /// The channels' context: the server holds it weakly, so it lives here.
    _context: Arc<Context>,
}

impl std::fmt::Debug for WorldServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WorldServer")
            .field("path", &self.path)
            .field("url", &self.url())
            .field("topics", &self.topics())
            .finish()
    }
}

/// `world.mcap` in the folder `world`, or `world` itself when a file.
fn world_file(world: &Path) -> Result<PathBuf> {
    if world.is_dir() {
        let f = world.join("world.mcap");
        if !f.is_file() {
            return Err(Error::invalid(
                "world",
                format!(
                    "{} holds no world.mcap (convert writes it into its output folder)",
                    world.display()
                ),
            ));
        }
        return Ok(f);
    }
    Ok(world.to_path_buf())
}

impl WorldServer {
    /// Serves `world` (a conversion's output folder, or its `world.mcap`)
    /// as `opts` say. Errors: no such file, a file that is not MCAP or has
    /// no channel, an address that cannot be bound (in use, not this
    /// machine's).
    pub fn start(world: &Path, opts: &ServeOptions) -> Result<Self> {
        let path = world_file(world)?;
        let server = Self::launch(path.clone(), opts, true)?;
        if server.topics().is_empty() {
            return Err(Error::Mcap {
                path,
                reason: "no channel to serve".into(),
            });
        }
        Ok(server)
    }

    /// Serves the world of a running conversion, each version handed to
    /// [`WorldServer::publish`] (nothing before the first); `path` names
    /// the file the conversion writes each version to, after publishing it
    /// ([`WorldServer::path`], and the name in errors). Errors: an address
    /// that cannot be bound.
    pub fn live(path: &Path, opts: &ServeOptions) -> Result<Self> {
        Self::launch(path.to_path_buf(), opts, false)
    }

    fn launch(path: PathBuf, opts: &ServeOptions, read: bool) -> Result<Self> {
        let context = Context::new();
        let topics = Arc::new(Mutex::new(Vec::new()));
        let mut served = Served {
            path: path.clone(),
            context: context.clone(),
            file: None,
            channels: HashMap::new(),
            topics_by_id: HashMap::new(),
            topics: topics.clone(),
        };
        if read {
            served.load()?;
        }
        let (tx, rx) = mpsc::channel();
        let listener = Arc::new(Listener {
            tx: Mutex::new(tx.clone()),
        });
        let server = WebSocketServer::new();
        // A world written again and again: a client's queue of a few worlds
        // (the SDK drops the oldest beyond it), not the SDK's 1024 messages
        // of up to 8 MB each for a client that reads nothing. A file is
        // served once, whole: the SDK's queue.
        let server = match read {
            true => server,
            false => server.message_backlog_size(LIVE_BACKLOG),
        };
        let handle = server
            .name("slam2world")
            .bind(opts.host.clone(), opts.port)
            .context(&context)
            .listener(listener)
            .start_blocking()
            .map_err(|e| {
                Error::invalid(
                    "serve",
                    format!("cannot listen on {}:{}: {e}", opts.host, opts.port),
                )
            })?;
        let port = handle.port();
        let worker = std::thread::Builder::new()
            .name("slam2world-serve".into())
            .spawn(move || work(served, &rx))
            .map_err(|e| Error::io(&path, e))?;
        Ok(WorldServer {
            path,
            host: opts.host.clone(),
            port,
            topics,
            handle: Some(handle),
            worker: Some(worker),
            tx,
            _context: context,
        })
    }

    /// The world as it now stands, `world.mcap`'s bytes: it goes to every
    /// subscriber (of the versions that pile up while one is sent, the
    /// latest), and to each client that subscribes later. Returns at once.
    pub fn publish(&self, world: Arc<Vec<u8>>) {
        let _ = self.tx.send(Request::Publish(world));
    }

    /// The port it listens on.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// `ws://HOST:PORT`, what Foxglove's "Open connection" takes.
    pub fn url(&self) -> String {
        if self.host.contains(':') {
            format!("ws://[{}]:{}", self.host, self.port)
        } else {
            format!("ws://{}:{}", self.host, self.port)
        }
    }

    /// The file served.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The topics served so far, in the order they were first served.
    pub fn topics(&self) -> Vec<String> {
        self.topics
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// Clients connected now.
    pub fn client_count(&self) -> usize {
        self.handle.as_ref().map_or(0, |h| h.client_count())
    }

    /// Stops serving: no client is accepted when this returns, and the
    /// clients are disconnected (one that reads nothing is left behind
    /// after 2 s, not waited for).
    pub fn stop(mut self) {
        self.shut_down();
    }

    fn shut_down(&mut self) {
        if let Some(h) = self.handle.take() {
            // The server stops accepting at once; its clients' tasks end as
            // their sends do, and a client that reads nothing never lets its
            // send end: it is left behind after STOP_WAIT (the process's end
            // closes it).
            let shutdown = h.stop();
            let (tx, rx) = mpsc::channel();
            let waiter = std::thread::Builder::new()
                .name("slam2world-serve-stop".into())
                .spawn(move || {
                    shutdown.wait_blocking();
                    let _ = tx.send(());
                });
            if waiter.is_ok() {
                let _ = rx.recv_timeout(STOP_WAIT);
            }
        }
        let _ = self.tx.send(Request::Stop);
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
    }
}

impl Drop for WorldServer {
    fn drop(&mut self) {
        self.shut_down();
    }
}

/// The worker: each subscription's channel read from the world and sent to
/// the client that asked, each version published to every subscriber,
/// until the server stops.
fn work(mut served: Served, rx: &mpsc::Receiver<Request>) {
    while let Ok(req) = rx.recv() {
        match req {
            Request::Stop => return,
            Request::Send { sink, channel } => served.send_subscribed(sink, channel),
            Request::Publish(mut world) => {
                // Versions queued behind this one replace it; the
                // subscriptions among them come after it.
                let mut later = Vec::new();
                let mut stop = false;
                while let Ok(r) = rx.try_recv() {
                    match r {
                        Request::Publish(w) => world = w,
                        Request::Stop => stop = true,
                        Request::Send { sink, channel } => later.push((sink, channel)),
                    }
                }
                // A version that cannot be read keeps the last one.
                let adopted =
                    McapFile::from_bytes(&served.path, world).and_then(|f| served.adopt(f));
                if adopted.is_ok() {
                    served.send(|_| true, None);
                }
                for (sink, channel) in later {
                    served.send_subscribed(sink, channel);
                }
                if stop {
                    return;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serve_at_is_a_port_or_a_host_and_port() {
        let at = |s: &str| s.parse::<ServeOptions>();
        assert_eq!(
            at("8765").unwrap(),
            ServeOptions {
                host: "127.0.0.1".into(),
                port: 8765
            }
        );
        assert_eq!(at("0.0.0.0:9000").unwrap().host, "0.0.0.0");
        assert_eq!(at("[::1]:0").unwrap().host, "::1");
        for bad in ["", "http", "host:", ":80", "1.2.3.4:70000"] {
            assert!(at(bad).is_err(), "{bad}");
        }
    }
}
