//! [`WsSource`]: the messages of a running Foxglove WebSocket server (the
//! SDK's, `foxglove_bridge`'s), as a client of its protocol
//! (github.com/foxglove/ws-protocol): the server's JSON `advertise` and
//! `unadvertise` are followed, the channels whose schema slam2world decodes
//! are subscribed, and the binary message frames (opcode 1: subscription id
//! `u32`, log time `u64`, payload; little-endian) come out as [`WsMessage`]s.

use std::collections::HashMap;
use std::net::TcpStream;
use std::time::Duration;

use tungstenite::client::IntoClientRequest;
use tungstenite::stream::MaybeTlsStream;
use tungstenite::{Message, WebSocket};

use crate::error::{Error, Result};
use crate::io::messages::decode::MessageKind;

/// The subprotocols offered: the current SDK's, then `foxglove_bridge`'s and
/// older servers'.
pub const SUBPROTOCOLS: &str = "foxglove.sdk.v1, foxglove.websocket.v1";

/// Largest message accepted (a keyframe of a large image with its depth,
/// variance and colour is a few MiB).
const MAX_MESSAGE: usize = 256 << 20;

/// A channel the server advertised.
#[derive(Clone, Debug, PartialEq)]
pub struct WsChannel {
    /// Topic.
    pub topic: String,
    /// Message encoding (`ros1`, `cdr`, `protobuf`, `json`).
    pub encoding: String,
    /// Schema name.
    pub schema_name: String,
    /// What slam2world reads it as (from the schema name).
    pub kind: Option<MessageKind>,
}

/// One message received.
#[derive(Clone, Debug)]
pub struct WsMessage {
    /// Its channel.
    pub channel: WsChannel,
    /// Log time, nanoseconds.
    pub log_time: u64,
    /// The payload, in the channel's encoding.
    pub data: Vec<u8>,
}

/// A connection to a Foxglove WebSocket server.
pub struct WsSource {
    url: String,
    socket: WebSocket<MaybeTlsStream<TcpStream>>,
    /// Advertised channels by the server's id.
    channels: HashMap<u64, WsChannel>,
    /// Subscriptions: our id to the server's channel id.
    subscriptions: HashMap<u32, u64>,
    next_subscription: u32,
    /// Subscriptions asked again, by channel ([`RESUBSCRIBE`] at most each).
    resubscribed: HashMap<u64, u32>,
    /// Messages received.
    pub received: u64,
}

/// Times a refused subscription to a channel is asked again: the Foxglove
/// SDK's server (0.30) sends a new channel's `advertise` before it records
/// the channel as advertised to the client, so a subscription sent back at
/// once can be refused as "Unknown channel ID".
const RESUBSCRIBE: u32 = 3;

impl std::fmt::Debug for WsSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WsSource")
            .field("url", &self.url)
            .field("channels", &self.channels.len())
            .field("received", &self.received)
            .finish()
    }
}

fn ws_err(url: &str, what: impl std::fmt::Display) -> Error {
    Error::invalid("source", format!("{url}: {what}"))
}

impl WsSource {
    /// Connects to `url` (`ws://HOST:PORT`), waiting at most `timeout` for
    /// the connection. Errors: a URL that is not `ws://`, no server there,
    /// a server that speaks neither subprotocol.
    pub fn connect(url: &str, timeout: Duration) -> Result<Self> {
        let mut request = url
            .into_client_request()
            .map_err(|e| ws_err(url, format!("not a WebSocket URL: {e}")))?;
        if request.uri().scheme_str() != Some("ws") {
            return Err(ws_err(url, "only ws:// is supported (no TLS)"));
        }
        request.headers_mut().insert(
            "Sec-WebSocket-Protocol",
            SUBPROTOCOLS
                .parse()
                .map_err(|e| ws_err(url, format!("subprotocol header: {e}")))?,
        );
        let authority = request
            .uri()
            .authority()
            .map(|a| a.as_str().to_string())
            .ok_or_else(|| ws_err(url, "no host"))?;
        let host_port = if authority.contains(':') {
            authority
        } else {
            format!("{authority}:80")
        };
        use std::net::ToSocketAddrs;
        let addr = host_port
            .to_socket_addrs()
            .map_err(|e| ws_err(url, e))?
            .next()
            .ok_or_else(|| ws_err(url, "no address"))?;
        let stream = TcpStream::connect_timeout(&addr, timeout).map_err(|e| ws_err(url, e))?;
        stream
            .set_read_timeout(Some(timeout))
            .map_err(|e| ws_err(url, e))?;
        let _ = stream.set_nodelay(true);
        let config = tungstenite::protocol::WebSocketConfig::default()
            .max_message_size(Some(MAX_MESSAGE))
            .max_frame_size(Some(MAX_MESSAGE));
        let (socket, response) = tungstenite::client::client_with_config(
            request,
            MaybeTlsStream::Plain(stream),
            Some(config),
        )
        .map_err(|e| ws_err(url, format!("handshake: {e}")))?;
        if response.headers().get("Sec-WebSocket-Protocol").is_none() {
            return Err(ws_err(
                url,
                format!("the server chose no subprotocol (offered {SUBPROTOCOLS})"),
            ));
        }
        Ok(WsSource {
            url: url.to_string(),
            socket,
            channels: HashMap::new(),
            subscriptions: HashMap::new(),
            next_subscription: 1,
            resubscribed: HashMap::new(),
            received: 0,
        })
    }

    /// Sets how long [`WsSource::recv`] waits for a frame.
    pub fn set_wait(&mut self, wait: Duration) -> Result<()> {
        if let MaybeTlsStream::Plain(s) = self.socket.get_mut() {
            s.set_read_timeout(Some(wait.max(Duration::from_millis(1))))
                .map_err(|e| ws_err(&self.url, e))?;
        }
        Ok(())
    }

    /// The next message of a subscribed channel; `None` when no frame
    /// came within the wait ([`WsSource::set_wait`]). Errors: the
    /// connection closed or broken, a frame that breaks the protocol (its
    /// reason said).
    pub fn recv(&mut self) -> Result<Option<WsMessage>> {
        loop {
            let frame = match self.socket.read() {
                Ok(f) => f,
                Err(tungstenite::Error::Io(e))
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    return Ok(None)
                }
                Err(e) => return Err(ws_err(&self.url, format!("connection: {e}"))),
            };
            match frame {
                Message::Text(t) => self.control(t.as_str())?,
                Message::Binary(b) => {
                    if let Some(m) = self.message(&b)? {
                        return Ok(Some(m));
                    }
                }
                Message::Close(c) => {
                    return Err(ws_err(
                        &self.url,
                        format!(
                            "the server closed the connection{}",
                            c.map(|c| format!(" ({})", c.reason)).unwrap_or_default()
                        ),
                    ))
                }
                _ => {}
            }
        }
    }

    /// A binary frame: a message of a subscription (others are skipped).
    fn message(&mut self, b: &[u8]) -> Result<Option<WsMessage>> {
        let Some((&op, rest)) = b.split_first() else {
            return Err(ws_err(&self.url, "an empty binary frame"));
        };
        if op != 1 {
            return Ok(None); // time, service responses, …
        }
        if rest.len() < 12 {
            return Err(ws_err(
                &self.url,
                format!("a message frame of {} bytes (at least 13)", b.len()),
            ));
        }
        let sub = u32::from_le_bytes([rest[0], rest[1], rest[2], rest[3]]);
        let mut t = [0u8; 8];
        t.copy_from_slice(&rest[4..12]);
        let Some(channel) = self
            .subscriptions
            .get(&sub)
            .and_then(|c| self.channels.get(c))
        else {
            // A message of a subscription just dropped.
            return Ok(None);
        };
        self.received += 1;
        Ok(Some(WsMessage {
            channel: channel.clone(),
            log_time: u64::from_le_bytes(t),
            data: rest[12..].to_vec(),
        }))
    }

    /// A JSON control message: channels advertised (those read subscribed)
    /// or withdrawn; the rest is not needed.
    fn control(&mut self, text: &str) -> Result<()> {
        let v: serde_json::Value = serde_json::from_str(text).map_err(|e| {
            ws_err(
                &self.url,
                format!("a control message that is not JSON: {e}"),
            )
        })?;
        match v.get("op").and_then(|o| o.as_str()) {
            Some("advertise") => {
                let Some(list) = v.get("channels").and_then(|c| c.as_array()) else {
                    return Err(ws_err(&self.url, "an advertise without channels"));
                };
                let mut subs = Vec::new();
                for c in list {
                    let field = |k: &str| c.get(k).and_then(|x| x.as_str()).unwrap_or_default();
                    let Some(id) = c.get("id").and_then(|x| x.as_u64()) else {
                        return Err(ws_err(&self.url, "an advertised channel without an id"));
                    };
                    let schema_name = field("schemaName").to_string();
                    let ch = WsChannel {
                        topic: field("topic").to_string(),
                        encoding: field("encoding").to_string(),
                        kind: MessageKind::from_schema(&schema_name),
                        schema_name,
                    };
                    let read = ch.kind.is_some();
                    if self.channels.insert(id, ch).is_none() && read {
                        let sub = self.next_subscription;
                        self.next_subscription += 1;
                        self.subscriptions.insert(sub, id);
                        subs.push(serde_json::json!({"id": sub, "channelId": id}));
                    }
                }
                if !subs.is_empty() {
                    let msg = serde_json::json!({"op": "subscribe", "subscriptions": subs});
                    self.socket
                        .send(Message::text(msg.to_string()))
                        .map_err(|e| ws_err(&self.url, format!("subscribe: {e}")))?;
                }
            }
            Some("status") => {
                // A subscription refused in the SDK's advertise race: asked
                // again (a few times at most), the channel still advertised.
                let text = v
                    .get("message")
                    .and_then(|m| m.as_str())
                    .unwrap_or_default();
                let refused = text
                    .strip_prefix("Unknown channel ID: ")
                    .and_then(|n| n.trim().parse::<u64>().ok());
                let Some(id) = refused else {
                    return Ok(());
                };
                let sub = self
                    .subscriptions
                    .iter()
                    .find_map(|(s, c)| (*c == id).then_some(*s));
                let tries = self.resubscribed.entry(id).or_insert(0);
                if let (Some(sub), true) = (sub, *tries < RESUBSCRIBE) {
                    *tries += 1;
                    std::thread::sleep(std::time::Duration::from_millis(10));
                    let msg = serde_json::json!({"op": "subscribe",
                        "subscriptions": [{"id": sub, "channelId": id}]});
                    self.socket
                        .send(Message::text(msg.to_string()))
                        .map_err(|e| ws_err(&self.url, format!("subscribe: {e}")))?;
                }
            }
            Some("unadvertise") => {
                if let Some(ids) = v.get("channelIds").and_then(|c| c.as_array()) {
                    for id in ids.iter().filter_map(|x| x.as_u64()) {
                        self.channels.remove(&id);
                        self.subscriptions.retain(|_, c| *c != id);
                    }
                }
            }
            _ => {}
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;
    use tungstenite::handshake::server::{Request, Response};

    /// A server on a free port that accepts one client (choosing
    /// `foxglove.sdk.v1` when `agree`) and sends it `frames`.
    fn server(agree: bool, frames: Vec<Message>) -> (String, std::thread::JoinHandle<()>) {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let url = format!("ws://{}", listener.local_addr().unwrap());
        let h = std::thread::spawn(move || {
            let (stream, _) = listener.accept().unwrap();
            let callback = |_: &Request, mut r: Response| {
                if agree {
                    r.headers_mut()
                        .insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
                }
                Ok(r)
            };
            let Ok(mut ws) = tungstenite::accept_hdr(stream, callback) else {
                return;
            };
            for f in frames {
                if ws.send(f).is_err() {
                    return;
                }
            }
            // Answer the subscription, then wait for the client to go.
            while ws.read().is_ok() {}
        });
        (url, h)
    }

    fn advertise() -> Message {
        Message::text(
            r#"{"op":"advertise","channels":[{"id":7,"topic":"/gt","encoding":"ros1",
            "schemaName":"geometry_msgs/PoseStamped","schema":"..."},{"id":8,"topic":"/img",
            "encoding":"ros1","schemaName":"sensor_msgs/Image","schema":"..."}]}"#,
        )
    }

    fn frame(sub: u32, t: u64, payload: &[u8]) -> Message {
        let mut b = vec![1u8];
        b.extend_from_slice(&sub.to_le_bytes());
        b.extend_from_slice(&t.to_le_bytes());
        b.extend_from_slice(payload);
        Message::binary(b)
    }

    #[test]
    fn advertised_channels_it_reads_are_subscribed_and_their_frames_decoded() {
        let (url, h) = server(
            true,
            vec![advertise(), frame(1, 42, b"abc"), frame(9, 1, b"x")],
        );
        let mut src = WsSource::connect(&url, Duration::from_secs(5)).unwrap();
        let m = src.recv().unwrap().unwrap();
        assert_eq!(m.channel.topic, "/gt");
        assert_eq!(m.channel.kind, Some(MessageKind::PoseStamped));
        assert_eq!((m.log_time, m.data.as_slice()), (42, &b"abc"[..]));
        // Subscription 9 is not ours: skipped; then nothing more comes.
        src.set_wait(Duration::from_millis(50)).unwrap();
        assert!(src.recv().unwrap().is_none());
        assert_eq!(src.received, 1);
        drop(src);
        h.join().unwrap();
    }

    #[test]
    fn a_subscription_refused_in_the_advertise_race_is_asked_again() {
        // The SDK's server refuses a subscription that overtakes its own
        // record of the advertise; the client asks again, a few times at most.
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let url = format!("ws://{}", listener.local_addr().unwrap());
        let h = std::thread::spawn(move || {
            let (stream, _) = listener.accept().unwrap();
            let callback = |_: &Request, mut r: Response| {
                r.headers_mut()
                    .insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
                Ok(r)
            };
            let mut ws = tungstenite::accept_hdr(stream, callback).unwrap();
            ws.send(advertise()).unwrap();
            let refused =
                Message::text(r#"{"op":"status","level":2,"message":"Unknown channel ID: 7"}"#);
            let mut subscribes = 0;
            while subscribes <= RESUBSCRIBE {
                let Ok(m) = ws.read() else { break };
                if m.to_text().is_ok_and(|t| t.contains("subscribe")) {
                    subscribes += 1;
                    ws.send(refused.clone()).unwrap();
                }
            }
            ws.send(frame(1, 5, b"late")).unwrap();
            while ws.read().is_ok() {}
            subscribes
        });
        let mut src = WsSource::connect(&url, Duration::from_secs(5)).unwrap();
        let m = src.recv().unwrap().unwrap();
        assert_eq!(
            (m.channel.topic.as_str(), m.data.as_slice()),
            ("/gt", &b"late"[..])
        );
        drop(src);
        // The first subscription and RESUBSCRIBE more, then no more.
        assert_eq!(h.join().unwrap(), 1 + RESUBSCRIBE);
    }

    #[test]
    fn a_hostile_server_gets_a_typed_error_not_a_crash() {
        let cases: Vec<(Vec<Message>, &str)> = vec![
            (vec![Message::text("{not json")], "not JSON"),
            (
                vec![Message::text(r#"{"op":"advertise"}"#)],
                "without channels",
            ),
            (
                vec![Message::text(
                    r#"{"op":"advertise","channels":[{"topic":"/a"}]}"#,
                )],
                "without an id",
            ),
            (
                vec![advertise(), Message::binary(vec![1u8, 2, 3])],
                "at least 13",
            ),
            (vec![Message::binary(Vec::new())], "empty binary frame"),
            (vec![Message::Close(None)], "closed the connection"),
        ];
        for (frames, want) in cases {
            let (url, h) = server(true, frames);
            let mut src = WsSource::connect(&url, Duration::from_secs(5)).unwrap();
            let e = loop {
                match src.recv() {
                    Ok(_) => continue,
                    Err(e) => break e.to_string(),
                }
            };
            assert!(e.contains(want), "{e} (want {want})");
            drop(src);
            h.join().unwrap();
        }
        // A server that chooses no subprotocol, and no server at all.
        let (url, h) = server(false, Vec::new());
        let e = WsSource::connect(&url, Duration::from_secs(5)).unwrap_err();
        assert!(e.to_string().contains("subprotocol"), "{e}");
        h.join().unwrap();
        let e = WsSource::connect("http://127.0.0.1:1", Duration::from_secs(1)).unwrap_err();
        assert!(e.to_string().contains("ws://"), "{e}");
    }
}
