"""Latency of `follow ws://… --serve`: from a keyframe's arrival to its points reaching a
Foxglove client, and the follower's memory, with a stalled client or without.

Usage::

    python benches/live_latency.py [--reduced K] [--seed S] [--stalled] [--live-points N]
                                   [--json PATH]

A simulated ground vehicle with no second sensor (`simulate --reduced K --no-reference
--no-imu`, the camera 1.2 m up; the follower scales from `--camera-height`) is published in
real time by the Foxglove SDK's own Python server (`foxglove-sdk`); `slam2world follow
ws://… --serve 0` follows it and serves its world; two clients, each a process of its own
written against the protocol on a plain socket, subscribe to everything the follower serves
(`--stalled` adds a third that subscribes and then never reads; `--live-points` is follow's
bound on the cloud sent at every update). For each keyframe the follower reports
(`/slam2world/state`, `last_keyframe`), the latency is the time from the publisher's `log()`
of that keyframe to the whole `/world/cloud` message of the first update naming it at a
reading client (an update sends the world in its order: the cloud, then the state). Prints
p50, p99 and max per client in milliseconds and the follower's peak resident memory
(`VmHWM`).
"""

from __future__ import annotations

import argparse
import base64
import json
import multiprocessing
import os
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import foxglove
import numpy as np
from mcap.reader import make_reader

from slam2world._slam2world import run_cli

SUBPROTOCOL = "foxglove.sdk.v1"
STATE = "/slam2world/state"


class Subscribed(foxglove.ServerListener):
    """Counts the subscriptions the publisher's server gets."""

    def __init__(self) -> None:
        self.count = 0

    def on_subscribe(self, client: Any, channel: Any) -> None:
        self.count += 1


class Peer:
    """A client of the protocol on a plain socket: the handshake and frames by hand (RFC 6455),
    each frame's payload received straight into one buffer (`recv_into`), so that what the bench
    measures is the server's delivery, not a Python websocket library's own cost (about 14 ms
    for each 8 MB frame with `websockets`)."""

    def __init__(self, url: str) -> None:
        host, port = url.removeprefix("ws://").rsplit(":", 1)
        self.buf = bytearray(1 << 16)
        self.sock = socket.create_connection((host, int(port)))
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall(
            (
                f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
                f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                f"Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: {SUBPROTOCOL}\r\n\r\n"
            ).encode()
        )
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(1)
            if not chunk:
                raise ConnectionError("closed during the handshake")
            head += chunk
        if b" 101 " not in head.split(b"\r\n", 1)[0]:
            raise ConnectionError(head.decode(errors="replace"))

    def _exact(self, n: int, idle: bool = False) -> memoryview:
        """The next `n` bytes, in a buffer that the next read reuses (a native client's
        receive buffer: fresh megabytes per frame would cost a page fault per page). The
        socket's timeout is raised only with `idle` and before the first byte (between
        frames), never inside a frame."""
        if len(self.buf) < n:
            self.buf = bytearray(n)
        buf = memoryview(self.buf)[:n]
        got = 0
        while got < n:
            try:
                k = self.sock.recv_into(buf[got:], n - got)
            except TimeoutError:
                if idle and got == 0:
                    raise
                continue
            if k == 0:
                raise ConnectionError("closed")
            got += k
        return buf

    def frame(self) -> tuple[int, memoryview]:
        """The next whole message: (opcode, payload); answers pings."""
        while True:
            b0, b1 = bytes(self._exact(2, idle=True))
            n = b1 & 0x7F
            if n == 126:
                (n,) = struct.unpack(">H", bytes(self._exact(2)))
            elif n == 127:
                (n,) = struct.unpack(">Q", bytes(self._exact(8)))
            payload = self._exact(n)
            opcode = b0 & 0x0F
            if opcode == 0x9:
                self.send(bytes(payload), opcode=0xA)
                continue
            if opcode == 0x8:
                raise ConnectionError("closed by the server")
            if not b0 & 0x80:
                raise ConnectionError("fragmented message (the SDK sends none)")
            return opcode, payload

    def send(self, body: bytes, opcode: int = 0x1) -> None:
        mask = os.urandom(4)
        n = len(body)
        if n < 126:
            header = bytes([0x80 | opcode, 0x80 | n])
        elif n < 1 << 16:
            header = bytes([0x80 | opcode, 0x80 | 126]) + struct.pack(">H", n)
        else:
            header = bytes([0x80 | opcode, 0x80 | 127]) + struct.pack(">Q", n)
        masked = np.frombuffer(body, np.uint8) ^ np.resize(np.frombuffer(mask, np.uint8), n)
        self.sock.sendall(header + mask + masked.tobytes())

    def subscribe_advertised(self, payload: memoryview, topics: dict[int, str]) -> None:
        """Subscribes to the channels an `advertise` names, and again to one whose subscription
        was refused as unknown: the SDK's server (foxglove 0.30) sends a new channel's
        `advertise` before it records the channel as advertised to the client, so a
        subscription that comes back at once can be refused."""
        msg = json.loads(bytes(payload))
        if msg.get("op") == "advertise":
            topics.update({c["id"]: c["topic"] for c in msg["channels"]})
            subs = [{"id": c["id"], "channelId": c["id"]} for c in msg["channels"]]
            self.send(json.dumps({"op": "subscribe", "subscriptions": subs}).encode())
        text = str(msg.get("message", "")) if msg.get("op") == "status" else ""
        if text.startswith("Unknown channel ID: ") and int(text.rsplit(" ", 1)[1]) in topics:
            cid = int(text.rsplit(" ", 1)[1])
            time.sleep(0.01)
            subs = [{"id": cid, "channelId": cid}]
            self.send(json.dumps({"op": "subscribe", "subscriptions": subs}).encode())


def reader_client(url: str, stop: Any, out: Any) -> None:
    """A process of its own (no interpreter lock shared with the publisher or the other
    client): subscribes to every channel as advertised; sends back (time the message was
    whole, topic, payload of the state messages)."""
    peer = Peer(url)
    peer.sock.settimeout(0.2)
    topics: dict[int, str] = {}
    got: list[tuple[float, str, bytes]] = []
    try:
        while not stop.is_set():
            try:
                opcode, payload = peer.frame()
            except TimeoutError:
                continue
            now = time.monotonic()
            if opcode == 0x1:
                peer.subscribe_advertised(payload, topics)
            elif opcode == 0x2 and payload[0] == 1:
                (sub,) = struct.unpack_from("<I", payload, 1)
                topic = topics[sub]
                got.append((now, topic, bytes(payload[13:]) if topic == STATE else b""))
    except (ConnectionError, OSError):
        pass
    out.send(got)


def stalled_client(url: str, stop: threading.Event) -> None:
    """Subscribes to every channel once the world's are advertised, then never reads again
    (its socket buffers fill, the server's queue for it with them)."""
    peer = Peer(url)
    peer.sock.settimeout(0.5)
    topics: dict[int, str] = {}
    # The world's channels are advertised one by one as the first world is served: every one
    # advertised until a second passes without a new one.
    deadline = time.monotonic() + 60.0
    quiet: float | None = None
    while time.monotonic() < (quiet or deadline) and not stop.is_set():
        try:
            opcode, payload = peer.frame()
        except TimeoutError:
            continue
        if opcode == 0x1:
            before = len(topics)
            peer.subscribe_advertised(payload, topics)
            if len(topics) > before:
                quiet = time.monotonic() + 1.0
    print(f"stalled client: subscribed to {len(topics)} channels, then reads nothing", flush=True)
    stop.wait()
    peer.sock.close()


def percentiles(ms: list[float]) -> dict[str, float]:
    a = np.asarray(ms)
    return {
        "n": len(a),
        "p50": float(np.percentile(a, 50)),
        "p99": float(np.percentile(a, 99)),
        "max": float(a.max()),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reduced", type=int, default=2)
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--stalled", action="store_true")
    ap.add_argument("--live-points", type=int, default=None)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="s2w-live-"))
    log, out = tmp / "run.mcap", tmp / "out"
    argv = ["slam2world", "simulate", "-o", str(log), "--reduced", str(args.reduced)]
    # A ground vehicle with no second sensor: the follower scales from its camera height as soon
    # as the floor is supported (a few keyframes in), so that most keyframes come after it.
    argv += ["--seed", str(args.seed), "--no-reference", "--no-imu"]
    for kv in ("camera_height=1.2", "height_loop=0", "height_slow=0", "look_height=0.6"):
        argv += ["--set", kv]
    assert run_cli(argv) == 0
    with log.open("rb") as f:
        msgs = list(make_reader(f).iter_messages(log_time_order=True))
    listener = Subscribed()
    server = foxglove.start_server(port=0, server_listener=listener)
    channels: dict[int, Any] = {}
    for s, c, _ in msgs:
        if c.id not in channels:
            schema = foxglove.Schema(name=s.name, encoding=s.encoding, data=s.data)
            channels[c.id] = foxglove.Channel(
                c.topic, message_encoding=c.message_encoding, schema=schema
            )
    follow = [
        sys.executable,
        "-m",
        "slam2world.cli",
        "follow",
        f"ws://127.0.0.1:{server.port}",
        "-o",
        str(out),
        "--serve",
        "0",
        "--camera-height",
        "1.2",
        "--idle-timeout",
        "3",
        "--grid",
        "0.25",
        "0.75",
        "-q",
    ]
    if args.live_points is not None:
        follow += ["--live-points", str(args.live_points)]
    proc = subprocess.Popen(follow, stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    serve_url = proc.stdout.readline().split(" on ", 1)[1].split(" ", 1)[0]
    stop = threading.Event()
    # The reading clients in processes of their own, the stalled one a thread here.
    spawn = multiprocessing.get_context("spawn")
    stop_readers = spawn.Event()
    pipes = [spawn.Pipe(duplex=False) for _ in range(2)]
    readers = [
        spawn.Process(target=reader_client, args=(serve_url, stop_readers, w)) for _, w in pipes
    ]
    for r in readers:
        r.start()
    threads = []
    if args.stalled:
        threads.append(threading.Thread(target=stalled_client, args=(serve_url, stop)))
    for t in threads:
        t.start()
    while listener.count == 0:
        time.sleep(0.05)
    time.sleep(0.5)
    published: dict[int, list[float]] = {}
    t0, wall0 = msgs[0][2].log_time, time.monotonic()
    for s, c, m in msgs:
        wait = (m.log_time - t0) * 1e-9 - (time.monotonic() - wall0)
        if wait > 0:
            time.sleep(wait)
        channels[c.id].log(m.data, log_time=m.log_time)
        if s.name.endswith("keyframeMsg") and m.data[12]:
            published.setdefault(struct.unpack_from("<i", m.data, 0)[0], []).append(
                time.monotonic()
            )
    time.sleep(1.0)
    server.stop()
    final = proc.stdout.readline()
    status = Path(f"/proc/{proc.pid}/status").read_text()
    hwm_kib = int(next(ln.split()[1] for ln in status.splitlines() if ln.startswith("VmHWM")))
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=30)
    stop_readers.set()
    got: list[list[tuple[float, str, bytes]]] = [r.recv() for r, _ in pipes]
    for r in readers:
        r.join(timeout=10)
    stop.set()
    for t in threads:
        t.join(timeout=10)
    result: dict[str, Any] = {
        "reduced": args.reduced,
        "stalled": args.stalled,
        "live_points": args.live_points,
        "keyframes": len(published),
        "follower_peak_rss_mib": hwm_kib / 1024,
        "end": final.strip(),
        "clients": [],
    }
    for g in got:
        # An update sends the world in its order: the cloud, then the state naming its keyframe.
        # A keyframe's points have reached the client with the first update that names it (one
        # may follow with the ground refitted).
        lat = []
        last_cloud: float | None = None
        seen: set[int] = set()
        for now, topic, payload in g:
            if topic == "/world/cloud":
                last_cloud = now
            elif topic == STATE and last_cloud is not None:
                st = json.loads(payload)
                k = st["last_keyframe"]
                sent = [t for t in published.get(k, []) if t <= last_cloud]
                if sent and k not in seen:
                    seen.add(k)
                    lat.append(1e3 * (last_cloud - sent[-1]))
                    if os.environ.get("S2W_DEBUG") and g is got[0]:
                        print(
                            f"kf {k} e2e {lat[-1]:.1f} ms; follower: "
                            + " ".join(
                                f"{n} {1e3 * st[n]:.1f}"
                                for n in ("decode_s", "fit_s", "backproject_s", "insert_s")
                            )
                            + f" rebuilds {st['rebuilds']} pub {sent[-1]:.6f} got {last_cloud:.6f}"
                        )
                last_cloud = None
        result["clients"].append(percentiles(lat) if lat else {"n": 0})
    if os.environ.get("S2W_DEBUG"):
        from collections import Counter

        print(Counter(t for _, t, _ in got[0]), sorted(published)[:10])
        print([json.loads(p)["last_keyframe"] for _, t, p in got[0] if p][:10])
    print(json.dumps(result, indent=1))
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
