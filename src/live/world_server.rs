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

/// What the listener asks of the worker.
enum Request {
    /// Send channel `channel`'s messages to client `sink`.
    Send { sink: SinkId, channel: ChannelId },
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

/// A channel of the file as served: its id in the file and the SDK's channel.
type Served = HashMap<ChannelId, (u16, Arc<RawChannel>)>;

/// A finished conversion's `world.mcap` served on a Foxglove WebSocket:
/// each channel of the file advertised as it is (topic, message encoding,
/// schema, metadata), and its messages sent, in the file's order and with
/// their log times, to each client that subscribes (when it subscribes: the
/// world is latched for late clients). The file is read again per
/// subscription, one channel's chunks at a time, so that the server holds
/// no more of a large world than one channel. Stops on [`WorldServer::stop`]
/// or when dropped.
pub struct WorldServer {
    path: PathBuf,
    host: String,
    port: u16,
    topics: Vec<String>,
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
            .field("topics", &self.topics)
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
        let file = McapFile::open(&path)?;
        let infos = file.channels()?;
        if infos.is_empty() {
            return Err(Error::Mcap {
                path,
                reason: "no channel to serve".into(),
            });
        }
        let ctx = Context::new();
        let mut served: Served = HashMap::new();
        let mut topics = Vec::new();
        for info in infos.values() {
            let schema = (info.schema_id != 0).then(|| {
                Schema::new(
                    info.schema_name.clone(),
                    info.schema_encoding.clone(),
                    info.schema_data.clone(),
                )
            });
            let channel = ChannelBuilder::new(info.topic.clone())
                .context(&ctx)
                .message_encoding(info.message_encoding.clone())
                .schema(schema)
                .metadata(info.metadata.clone())
                .build_raw()
                .map_err(|e| Error::Mcap {
                    path: path.clone(),
                    reason: format!("channel {}: {e}", info.topic),
                })?;
            topics.push(info.topic.clone());
            served.insert(channel.id(), (info.id, channel));
        }
        let (tx, rx) = mpsc::channel();
        let listener = Arc::new(Listener {
            tx: Mutex::new(tx.clone()),
        });
        let handle = WebSocketServer::new()
            .name("slam2world")
            .bind(opts.host.clone(), opts.port)
            .context(&ctx)
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
            .spawn(move || send_on_request(&file, &served, &rx))
            .map_err(|e| Error::io(&path, e))?;
        Ok(WorldServer {
            path,
            host: opts.host.clone(),
            port,
            topics,
            handle: Some(handle),
            worker: Some(worker),
            tx,
            _context: ctx,
        })
    }

    /// The port it listens on.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// `ws://HOST:PORT`, what Foxglove's "Open connection" takes.
    pub fn url(&self) -> String {
        format!("ws://{}:{}", self.host, self.port)
    }

    /// The file served.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The topics served, in the file's channel order.
    pub fn topics(&self) -> &[String] {
        &self.topics
    }

    /// Clients connected now.
    pub fn client_count(&self) -> usize {
        self.handle.as_ref().map_or(0, |h| h.client_count())
    }

    /// Stops serving: the clients are disconnected and the port is free
    /// when this returns.
    pub fn stop(mut self) {
        self.shut_down();
    }

    fn shut_down(&mut self) {
        if let Some(h) = self.handle.take() {
            h.stop().wait_blocking();
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

/// The worker: each subscription's channel read from the file and sent to
/// the client that asked, until the server stops.
fn send_on_request(file: &McapFile, served: &Served, rx: &mpsc::Receiver<Request>) {
    while let Ok(Request::Send { sink, channel }) = rx.recv() {
        let Some((id, out)) = served.get(&channel) else {
            continue;
        };
        // The file was read whole at the start; one that changed since
        // sends nothing more.
        let Ok(scan) = file.scan(|c| c.id == *id) else {
            continue;
        };
        for m in scan.iter() {
            out.log_with_meta_to_sink(
                m.data,
                PartialMetadata {
                    log_time: Some(m.log_time),
                },
                Some(sink),
            );
        }
    }
}
