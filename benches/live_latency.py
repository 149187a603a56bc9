"""Latency of `follow ws://… --serve`: from a keyframe's arrival to its points reaching a
Foxglove client, and the follower's memory, with a stalled client or without.

Usage::

    python benches/live_latency.py [--reduced K] [--seed S] [--stalled] [--live-points N]
                                   [--json PATH]

A simulated ground vehicle with no second sensor (`simulate --reduced K --no-reference
--no-imu`, the camera 1.2 m up; the follower scales from `--camera-height`) is published in
real time by the Foxglove SDK's own Python server (`foxglove-sdk`); `slam2world follow
ws://… --serve 0` follows it and serves its world; two clients written against the protocol
subscribe to everything the follower serves (`--stalled` adds a third that subscribes and
then never reads; `--live-points` is follow's bound on the cloud sent at every update). For
each keyframe the follower
reports (`/slam2world/state`, `last_keyframe`), the latency is the time from the publisher's
`log()` of that keyframe to the `/world/cloud` message of the same refresh at a reading client
(a refresh sends the file in its order: the cloud, then the state). Prints p50, p99 and max
per client in milliseconds and the follower's peak resident memory (`VmHWM`).
"""

from __future__ import annotations

import argparse
import base64
import json
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
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from slam2world._slam2world import run_cli

SUBPROTOCOL = "foxglove.sdk.v1"


class Subscribed(foxglove.ServerListener):
    """Counts the subscriptions the publisher's server gets."""

    def __init__(self) -> None:
        self.count = 0

    def on_subscribe(self, client: Any, channel: Any) -> None:
        self.count += 1


def reader_client(url: str, stop: threading.Event, out: list[tuple[float, str, bytes]]) -> None:
    """Subscribes to every channel as advertised; keeps (receive time, topic, payload of the
    state messages)."""
    with connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
        topics: dict[int, str] = {}
        while not stop.is_set():
            try:
                frame = ws.recv(timeout=0.2)
            except TimeoutError:
                continue
            except ConnectionClosed:
                return
            now = time.monotonic()
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg["op"] == "advertise":
                    subs = [{"id": c["id"], "channelId": c["id"]} for c in msg["channels"]]
                    topics.update({c["id"]: c["topic"] for c in msg["channels"]})
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                continue
            (sub,) = struct.unpack_from("<I", frame, 1)
            topic = topics[sub]
            out.append((now, topic, bytes(frame[13:]) if topic == "/slam2world/state" else b""))


def stalled_client(url: str, stop: threading.Event) -> None:
    """Handshakes by hand, subscribes to every channel once the world's are advertised, then
    never reads again (its socket buffers fill, the server's queue for it with them)."""
    host, port = url.removeprefix("ws://").rsplit(":", 1)
    s = socket.create_connection((host, int(port)))
    key = base64.b64encode(os.urandom(16)).decode()
    s.sendall(
        (
            f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
            f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
            f"Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: {SUBPROTOCOL}\r\n\r\n"
        ).encode()
    )
    # Read until the world's channels are advertised (once the follower has a transform).
    s.settimeout(0.5)
    seen = b""
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline and b'"topic"' not in seen and not stop.is_set():
        try:
            seen += s.recv(65536)
        except TimeoutError:
            continue
    time.sleep(0.2)
    try:
        seen += s.recv(1 << 20)
    except TimeoutError:
        pass
    ids = [int(x) for x in _ids(seen)]
    print(f"stalled client: subscribed to {len(ids)} channels, then reads nothing", flush=True)
    body = json.dumps(
        {"op": "subscribe", "subscriptions": [{"id": i, "channelId": i} for i in ids]}
    ).encode()
    mask = os.urandom(4)
    header = bytes([0x81, 0x80 | 126]) + struct.pack(">H", len(body)) + mask
    s.sendall(header + bytes(b ^ mask[i % 4] for i, b in enumerate(body)))
    stop.wait()
    s.close()


def _ids(data: bytes) -> list[str]:
    """Channel ids in the advertise messages among `data` (text frames, unmasked)."""
    out = []
    for part in data.split(b'"channels":')[1:]:
        for seg in part.split(b'"id":')[1:]:
            digits = seg[: next((i for i, c in enumerate(seg) if not chr(c).isdigit()), len(seg))]
            if digits:
                out.append(digits.decode())
    return out


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
    got: list[list[tuple[float, str, bytes]]] = [[], []]
    threads = [threading.Thread(target=reader_client, args=(serve_url, stop, g)) for g in got]
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
        # A refresh sends the file in its order: the cloud, then the state naming its keyframe.
        lat = []
        last_cloud: float | None = None
        for now, topic, payload in g:
            if topic == "/world/cloud":
                last_cloud = now
            elif topic == "/slam2world/state" and last_cloud is not None:
                k = json.loads(payload)["last_keyframe"]
                sent = [t for t in published.get(k, []) if t <= last_cloud]
                if sent:
                    lat.append(1e3 * (last_cloud - sent[-1]))
                    if os.environ.get("S2W_DEBUG") and g is got[0]:
                        st = json.loads(payload)
                        print(
                            f"kf {k} e2e {lat[-1]:.1f} ms; follower: "
                            + " ".join(
                                f"{n} {1e3 * st[n]:.1f}"
                                for n in ("decode_s", "fit_s", "backproject_s", "insert_s")
                            )
                            + f" rebuilds {st['rebuilds']}"
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
