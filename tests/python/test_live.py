"""Live in Foxglove. Out: a converted world served on a Foxglove WebSocket (`slam2world serve OUT/`,
`slam2world.serve`), checked by a client written against the protocol's specification
(github.com/foxglove/ws-protocol, subprotocol `foxglove.sdk.v1`): a plain `websockets` client
that reads the server's JSON `serverInfo` and `advertise`, sends `subscribe`, and decodes the
binary message frames (opcode 1: subscription id u32, log time u64, payload; little-endian).
What it receives is compared with `world.mcap` as the `mcap` package reads it. In: `follow
ws://` against the Foxglove SDK's own Python server (`foxglove-sdk` from PyPI)."""

from __future__ import annotations

import base64
import json
import os
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import foxglove
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

import slam2world as sw
from slam2world._slam2world import run_cli

SUBPROTOCOL = "foxglove.sdk.v1"


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated run converted with its octree: `OUT/world.mcap`."""
    d = tmp_path_factory.mktemp("live")
    log, out = d / "run.mcap", d / "out"
    assert run_cli(["slam2world", "simulate", "-o", str(log), "--reduced", "4"]) == 0
    args = ["convert", str(log), "-o", str(out), "-q", "--octree", "0.2", "--grid", "0.1", "1.0"]
    assert run_cli(["slam2world", *args]) == 0
    return out


def file_messages(path: Path) -> tuple[dict[str, dict], dict[str, list[tuple[int, bytes]]]]:
    """Channels (topic -> encoding and schema) and messages (topic -> (log time, data)) of an
    MCAP file, read by the `mcap` package."""
    channels: dict[str, dict] = {}
    messages: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
    with path.open("rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            channels[channel.topic] = {
                "encoding": channel.message_encoding,
                "schemaName": schema.name if schema else "",
                "schemaEncoding": schema.encoding if schema else "",
                "schema": schema.data if schema else b"",
            }
            messages[channel.topic].append((message.log_time, bytes(message.data)))
    return channels, dict(messages)


def receive_world(url: str, want: dict[str, int], timeout: float = 30.0) -> tuple[dict, dict]:
    """Connects to `url`, subscribes to every advertised channel and collects its messages
    until each topic has `want[topic]` of them: (advertised channels by topic, messages by
    topic)."""
    advertised: dict[str, dict] = {}
    got: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
    with connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
        assert ws.subprotocol == SUBPROTOCOL
        info = json.loads(ws.recv(timeout=timeout))
        assert info["op"] == "serverInfo" and info["name"] == "slam2world"
        by_sub: dict[int, str] = {}
        deadline = time.monotonic() + timeout
        while any(len(got[t]) < n for t, n in want.items()):
            frame = ws.recv(timeout=max(0.1, deadline - time.monotonic()))
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg["op"] == "advertise":
                    subs = []
                    for ch in msg["channels"]:
                        advertised[ch["topic"]] = ch
                        sub = len(by_sub) + 1
                        by_sub[sub] = ch["topic"]
                        subs.append({"id": sub, "channelId": ch["id"]})
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                continue
            assert frame[0] == 1, f"opcode {frame[0]}"
            sub, log_time = struct.unpack_from("<IQ", frame, 1)
            got[by_sub[sub]].append((log_time, bytes(frame[13:])))
    return advertised, dict(got)


def collect(
    url: str,
    received: dict[str, list[tuple[int, bytes]]],
    stop: threading.Event,
    errors: list[BaseException],
) -> None:
    """Subscribes to every channel of `url` as it is advertised and keeps what arrives in
    `received` (by topic) until `stop`; an error goes to `errors`."""
    try:
        with connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
            topics: dict[int, str] = {}
            while not stop.is_set():
                try:
                    frame = ws.recv(timeout=0.2)
                except TimeoutError:
                    continue
                if isinstance(frame, str):
                    msg = json.loads(frame)
                    if msg["op"] == "advertise":
                        subs = []
                        for ch in msg["channels"]:
                            topics[ch["id"]] = ch["topic"]
                            subs.append({"id": ch["id"], "channelId": ch["id"]})
                        ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                    elif (cid := refused_channel(msg)) in topics:
                        # The SDK's server (foxglove 0.30) sends a new channel's `advertise`
                        # before it records the channel as advertised to the client: a
                        # subscription that comes back at once can be refused. Ask again.
                        time.sleep(0.01)
                        sub = {"id": cid, "channelId": cid}
                        ws.send(json.dumps({"op": "subscribe", "subscriptions": [sub]}))
                    continue
                sub, log_time = struct.unpack_from("<IQ", frame, 1)
                received[topics[sub]].append((log_time, bytes(frame[13:])))
    except BaseException as e:  # noqa: BLE001 - reported by the test that collects
        errors.append(e)


def refused_channel(msg: dict) -> int | None:
    """The channel of an error `status` that refused a subscription ("Unknown channel ID: N")."""
    text = str(msg.get("message", "")) if msg.get("op") == "status" else ""
    head = "Unknown channel ID: "
    return int(text[len(head) :]) if text.startswith(head) else None


def wait_for_file(received: dict[str, list[tuple[int, bytes]]], path: Path) -> dict:
    """Waits (30 s at most) until the last messages received of each topic are those `path`
    holds; returns the file's messages by topic."""
    _, messages = file_messages(path)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and any(
        received[t][-len(m) :] != m for t, m in messages.items()
    ):
        time.sleep(0.1)
    return messages


def schema_bytes(ch: dict) -> bytes:
    """An advertised channel's schema as bytes: base64 for binary encodings (protobuf)."""
    if ch.get("schemaEncoding") == "protobuf":
        return base64.b64decode(ch["schema"])
    return str(ch.get("schema", "")).encode()


@pytest.mark.slow
def test_a_client_of_the_protocol_gets_every_channel_of_world_mcap(world: Path) -> None:
    channels, messages = file_messages(world / "world.mcap")
    assert {"/world/cloud", "/tf", "/world/slam_trajectory", "/slam2world/octomap"} <= set(channels)
    want = {t: len(m) for t, m in messages.items()}
    with sw.serve(world, port=0) as srv:
        assert srv.url == f"ws://127.0.0.1:{srv.port}" and srv.running
        assert sorted(srv.topics) == sorted(channels)
        # Two clients, the second after the first has it all: the world is latched.
        for _ in range(2):
            advertised, got = receive_world(srv.url, want)
            assert set(advertised) == set(channels)
            for topic, ch in channels.items():
                a = advertised[topic]
                assert a["encoding"] == ch["encoding"] and a["schemaName"] == ch["schemaName"]
                assert a["schemaEncoding"] == ch["schemaEncoding"]
                assert schema_bytes(a) == ch["schema"], topic
                assert got[topic] == messages[topic], topic
    assert not srv.running
    # Nothing listens there any more.
    with pytest.raises(ConnectionRefusedError), socket.socket() as s:
        s.connect(("127.0.0.1", srv.port))


def test_the_layout_is_the_sdk_s_and_names_the_topics_the_world_has(
    world: Path, tmp_path: Path
) -> None:
    """The Foxglove layout shipped (`slam2world layout`, `foxglove_layout()`) is what
    `src/live/layout.py` builds with the Foxglove SDK's layout API today, and its 3-D panel
    has a setting for every topic of the world but the transforms."""
    import importlib.util

    script = Path(__file__).parents[2] / "src" / "live" / "layout.py"
    spec = importlib.util.spec_from_file_location("s2w_layout", script)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert sw.foxglove_layout() == module.layout_json()
    assert run_cli(["slam2world", "layout", "-o", str(tmp_path / "layout.json")]) == 0
    assert (tmp_path / "layout.json").read_text() == sw.foxglove_layout()

    named: set[str] = set()
    scene: set[str] = set()

    def walk(node: Any) -> None:
        if isinstance(node, dict):
            if node.get("panelType") == "ThreeDee":
                scene.update(node["config"]["topics"])
            for key in ("topicPath", "value"):
                if isinstance(node.get(key), str) and node[key].startswith("/"):
                    named.add(node[key].split(".", 1)[0])
            for v in node.values():
                walk(v)
        elif isinstance(node, list):
            for v in node:
                walk(v)

    walk(json.loads(sw.foxglove_layout()))
    channels, _ = file_messages(world / "world.mcap")
    assert scene == set(channels) - {"/tf"}
    assert named == {"/slam2world/state"}


def test_bad_worlds_and_taken_ports_are_refused_with_the_reason(
    world: Path, tmp_path: Path
) -> None:
    with pytest.raises(sw.InvalidInputError, match="no world.mcap"):
        sw.serve(tmp_path, port=0)
    with pytest.raises(sw.FileError, match="No such file"):
        sw.serve(tmp_path / "missing.mcap", port=0)
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not an mcap file at all")
    with pytest.raises(sw.FormatError):
        sw.serve(bad, port=0)
    with sw.serve(world, port=0) as srv:
        with pytest.raises(sw.InvalidInputError, match="cannot listen"):
            sw.serve(world, port=srv.port)
        srv.stop()
        srv.stop()  # again: nothing


@pytest.mark.slow
def test_the_cli_serves_until_ctrl_c(world: Path) -> None:
    argv = [sys.executable, "-m", "slam2world.cli", "serve", str(world), "--port", "0"]
    with subprocess.Popen(argv, stdout=subprocess.PIPE, text=True) as proc:
        try:
            assert proc.stdout is not None
            line = proc.stdout.readline()
            assert line.startswith(f"serving {world / 'world.mcap'} on ws://127.0.0.1:"), line
            url = line.split(" on ", 1)[1].split(" ", 1)[0]
            _, messages = file_messages(world / "world.mcap")
            _, got = receive_world(url, {"/tf": len(messages["/tf"])})
            assert got["/tf"] == messages["/tf"]
            proc.send_signal(signal.SIGINT)
            assert proc.wait(timeout=20) == 0
        finally:
            if proc.poll() is None:
                proc.kill()


@pytest.mark.slow
def test_follow_serves_the_world_as_it_is_written_and_the_final_one_until_ctrl_c(
    tmp_path: Path,
) -> None:
    log, out = tmp_path / "run.mcap", tmp_path / "out"
    assert run_cli(["slam2world", "simulate", "-o", str(log), "--reduced", "4"]) == 0
    argv = [sys.executable, "-m", "slam2world.cli", "follow", str(log), "-o", str(out)]
    argv += ["--serve", "0", "--grid", "0.1", "1.0", "--stable-hold", "0.3", "-q"]
    argv += ["--live-points", "5000"]
    received: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
    errors: list[BaseException] = []
    stop = threading.Event()
    with subprocess.Popen(argv, stdout=subprocess.PIPE, text=True) as proc:
        try:
            assert proc.stdout is not None
            line = proc.stdout.readline()
            assert line.startswith(f"serving {out / 'world.mcap'} on ws://127.0.0.1:"), line
            url = line.split(" on ", 1)[1].split(" ", 1)[0]
            client = threading.Thread(target=collect, args=(url, received, stop, errors))
            client.start()
            # Serving the final world: the file no longer changes.
            line = proc.stdout.readline()
            assert line.startswith("follow: serving the final world on "), line
            messages = wait_for_file(received, out / "world.mcap")
            assert {"/tf", "/slam2world/octomap", "/slam2world/grid", "/slam2world/state"} <= set(
                messages
            )
            stop.set()
            client.join(timeout=10)
            assert errors == []
            for topic, m in messages.items():
                assert received[topic][-len(m) :] == m, topic
            # The session's state as JSON: report.json's, at the end.
            state = json.loads(received["/slam2world/state"][-1][1])
            assert state == json.loads((out / "report.json").read_text())
            assert state["finished"] and state["stage"] == "stable"
            assert {"/world/cloud", "/world/slam_trajectory"} <= set(messages)
            # The cloud within --live-points (16 bytes a point).
            with (out / "world.mcap").open("rb") as f:
                reader = make_reader(f, decoder_factories=[ProtobufDecoderFactory()])
                (pc,) = [m for _, _, _, m in reader.iter_decoded_messages(["/world/cloud"])]
            assert pc.point_stride == 16 and 1000 < len(pc.data) // 16 <= 5000
            proc.send_signal(signal.SIGINT)
            assert proc.wait(timeout=20) == 0
        finally:
            stop.set()
            if proc.poll() is None:
                proc.kill()


@pytest.mark.slow
def test_a_session_serves_its_world_as_it_grows() -> None:
    """`Session.serve`: the session pushed from Python publishes each world on a Foxglove
    WebSocket, with the reference path and the state; a client gets what the served file
    holds at the end; the serving stops and starts again without the session noticing."""
    sim = sw.simulate(seed=3, reduced=4)
    s = sw.Session(stable_hold=1.0)
    with pytest.raises(sw.InvalidInputError, match="z_min"):
        s.serve(0, grid=(1.0, 0.0))
    with pytest.raises(sw.InvalidInputError, match="points"):
        s.serve(0, points=0)
    srv = s.serve(0, grid=(0.25, 0.75))
    assert srv.running and srv.url == f"ws://127.0.0.1:{srv.port}"
    assert srv.topics == []  # nothing before the transform
    with pytest.raises(sw.InvalidInputError, match="cannot listen"):
        sw.Session().serve(srv.port)
    received: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
    errors: list[BaseException] = []
    stop = threading.Event()
    client = threading.Thread(target=collect, args=(srv.url, received, stop, errors))
    client.start()
    try:
        time.sleep(0.3)
        rt, rp, rq = sim.reference_timestamps, sim.reference_positions, sim.reference_orientations
        assert rq is not None
        ft, fp, fq = sim.slam_timestamps, sim.slam_positions, sim.slam_orientations
        assert fq is not None
        events = [(float(t), 0, i) for i, t in enumerate(rt)]
        events += [(float(t), 1, i) for i, t in enumerate(ft)]
        events += [(float(t), 2, i) for i, t in enumerate(sim.keyframe_timestamps)]
        keyframes = sim.keyframes
        first_world = None
        for _, kind, i in sorted(events):
            if kind == 0:
                s.push_reference(float(rt[i]), rp[i].tolist(), rq[i].tolist())
            elif kind == 1:
                s.push_frame(float(ft[i]), sw.Sim3.from_quaternion(fq[i], fp[i], 1.0))
            else:
                s.push_keyframe(keyframes[i])
                if first_world is None and s.transform() is not None:
                    first_world = i
        s.finish()
        assert first_world is not None and first_world < len(keyframes) - 1
        messages = wait_for_file(received, srv.path)
        stop.set()
        client.join(timeout=10)
        assert errors == []
        assert {"/world/cloud", "/world/reference", "/tf", "/slam2world/grid"} <= set(messages)
        for topic, m in messages.items():
            assert received[topic][-len(m) :] == m, topic
        # A world per keyframe from the first with a transform, and the end's.
        states = [json.loads(d) for _, d in received["/slam2world/state"]]
        assert len(states) >= 2 and states[-1]["finished"] and not states[0]["finished"]
        t = s.transform()
        assert t is not None and states[-1]["t_world_slam"]["scale"] == pytest.approx(t.scale)
        assert sorted(srv.topics) == sorted(messages)
        # The frames under the world: slam, the latest keyframe's camera, the latest
        # reference pose's body.
        with srv.path.open("rb") as f:
            reader = make_reader(f, decoder_factories=[ProtobufDecoderFactory()])
            tf = {m.child_frame_id: m for _, _, _, m in reader.iter_decoded_messages(["/tf"])}
        assert set(tf) == {"slam", "camera", "body"}
        assert all(m.parent_frame_id == "world" for m in tf.values())
        b = tf["body"].translation
        assert [b.x, b.y, b.z] == pytest.approx(rp[-1].tolist(), abs=1e-12)
        c = tf["camera"].translation
        last = max(keyframes, key=lambda k: k.timestamp)
        want = (t @ last.pose).translation
        assert [c.x, c.y, c.z] == pytest.approx(want.tolist(), abs=1e-9)
    finally:
        stop.set()
        srv.stop()
    assert not srv.running
    # Served again: the world the session holds goes out at once.
    with s.serve(0) as again:
        _, got = receive_world(again.url, {"/world/cloud": 1, "/slam2world/state": 1})
        assert json.loads(got["/slam2world/state"][-1][1])["stage"] == "stable"


@pytest.mark.slow
def test_a_served_session_sends_a_keyframe_before_the_refit_it_calls_for() -> None:
    """With a camera height, a keyframe that calls for a ground refit goes to the clients
    carried by the transform the session had, and the refitted world follows at once: two
    states name that keyframe, the first with the scale the keyframe before ended on. After
    every push the session is where one that is not served is, bit for bit."""
    sim = sw.simulate(
        reduced=4, seed=3, camera_height=1.2, height_loop=0.0, height_slow=0.0, look_height=0.6
    )
    served, plain = sw.Session(camera_height=1.2), sw.Session(camera_height=1.2)
    srv = served.serve(0)
    received: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
    errors: list[BaseException] = []
    stop = threading.Event()
    client = threading.Thread(target=collect, args=(srv.url, received, stop, errors))
    client.start()

    def states() -> list[dict]:
        return [json.loads(d) for _, d in list(received["/slam2world/state"])]

    try:
        time.sleep(0.3)
        order = []
        for kf in sim.keyframes:
            served.push_keyframe(kf)
            plain.push_keyframe(kf)
            a, b = served.transform(), plain.transform()
            assert (a is None) == (b is None)
            if a is None or b is None:
                continue
            assert (a.scale, a.translation.tolist()) == (b.scale, b.translation.tolist())
            order.append(kf.id)
            # Paced: the world of this push (the refitted one, when there is one) arrived.
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and not any(
                s["last_keyframe"] == kf.id and s["t_world_slam"]["scale"] == a.scale
                for s in states()
            ):
                time.sleep(0.01)
        assert errors == []
        last: dict[int, list[float]] = defaultdict(list)
        for s in states():
            last[s["last_keyframe"]].append(s["t_world_slam"]["scale"])
        assert [k for k in last if k in order] == order
        twice = [i for i, k in enumerate(order) if len(last[k]) == 2]
        assert len(twice) >= 3, last
        for i in twice:
            first, refitted = last[order[i]]
            assert i > 0 and first == last[order[i - 1]][-1] and refitted != first
        assert all(len(last[k]) == 1 for i, k in enumerate(order) if i not in twice)
    finally:
        stop.set()
        client.join(timeout=10)
        srv.stop()


class _Subscriptions(foxglove.ServerListener):
    """Counts the subscriptions a server gets, by topic."""

    def __init__(self) -> None:
        self.topics: list[str] = []

    def on_subscribe(self, client: foxglove.websocket.Client, channel: Any) -> None:
        self.topics.append(channel.topic)


class _SdkServer:
    """The Foxglove SDK's server on `port` with a channel for each of the log's, in a context
    of its own (a server started again advertises its own channels only; the SDK holds the
    context weakly, so it is kept here)."""

    def __init__(self, msgs: list, port: int = 0) -> None:
        self.listener = _Subscriptions()
        self.context = foxglove.Context()
        self.server = foxglove.start_server(
            port=port, server_listener=self.listener, context=self.context
        )
        self.channels: dict[int, foxglove.Channel] = {}
        for sch, c, _ in msgs:
            if c.id not in self.channels:
                schema = foxglove.Schema(name=sch.name, encoding=sch.encoding, data=sch.data)
                self.channels[c.id] = foxglove.Channel(
                    c.topic,
                    message_encoding=c.message_encoding,
                    schema=schema,
                    context=self.context,
                )


def _publish(msgs: list, channels: dict[int, foxglove.Channel]) -> None:
    """Logs `msgs` on `channels` at the pace of their log times."""
    t0, wall0 = msgs[0][2].log_time, time.monotonic()
    for _, c, m in msgs:
        wait = (m.log_time - t0) * 1e-9 - (time.monotonic() - wall0)
        if wait > 0:
            time.sleep(wait)
        channels[c.id].log(m.data, log_time=m.log_time)


def _wait_subscribed(listener: _Subscriptions) -> None:
    deadline = time.monotonic() + 30
    while not listener.topics and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)
    assert {"/lsd_slam/keyframes", "/ground_truth/pose"} <= set(listener.topics)


def _ends_as_convert(log: Path, out: Path, tmp_path: Path) -> Any:
    """Asserts that `follow`'s report and `map.bt` in `out` end on `convert`'s transform scale
    and octree of `log`; returns the conversion."""
    report = json.loads((out / "report.json").read_text())
    conv = sw.convert(log, skip_init="auto", octree_resolution=0.1, octree_max_range=10.0)
    t = conv.report["t_world_slam"]
    assert report["t_world_slam"]["scale"] == pytest.approx(t["scale"], rel=1e-9)
    assert conv.octree is not None
    conv.octree.write_bt(tmp_path / "batch.bt")
    assert (out / "map.bt").read_bytes() == (tmp_path / "batch.bt").read_bytes()
    return conv


@pytest.mark.slow
def test_follow_a_foxglove_sdk_server_ends_where_convert_of_the_log_does(tmp_path: Path) -> None:
    """The Foxglove SDK's own Python server (not this project's code) publishes a simulated run's
    messages in real time; `follow ws://` subscribes, follows, sees the server go, and ends on
    the transform and the octree that `convert` of the same log gives."""
    log, out = tmp_path / "run.mcap", tmp_path / "out"
    argv = ["slam2world", "simulate", "-o", str(log), "--reduced", "8", "--seed", "2"]
    assert run_cli(argv) == 0
    with log.open("rb") as f:
        msgs = list(make_reader(f).iter_messages(log_time_order=True))
    sdk = _SdkServer(msgs)
    url = f"ws://127.0.0.1:{sdk.server.port}"
    follow = [sys.executable, "-m", "slam2world.cli", "follow", url, "-o", str(out)]
    follow += ["--stable-hold", "0.3", "--idle-timeout", "3", "--grid", "0.25", "0.75", "-q"]
    with subprocess.Popen(follow, stderr=subprocess.PIPE, text=True) as proc:
        try:
            # Published once the client has subscribed (one subscribe for all it reads).
            _wait_subscribed(sdk.listener)
            _publish(msgs, sdk.channels)
            time.sleep(1.0)
            sdk.server.stop()
            assert proc.wait(timeout=60) == 0
            assert proc.stderr is not None
            assert "connection lost" in proc.stderr.read()
        finally:
            sdk.server.stop()
            if proc.poll() is None:
                proc.kill()
    report = json.loads((out / "report.json").read_text())
    assert report["finished"] and report["end"].startswith("server gone")
    assert report["disconnections"] == 1
    conv = _ends_as_convert(log, out, tmp_path)
    t = conv.report["t_world_slam"]
    assert report["t_world_slam"]["translation"] == pytest.approx(t["translation"], abs=1e-9)
    # follow's world cloud: convert's points, every k-th of them (bounded for a viewer).
    with (out / "world.mcap").open("rb") as f:
        reader = make_reader(f, decoder_factories=[ProtobufDecoderFactory()])
        clouds = [m for _, _, _, m in reader.iter_decoded_messages(topics=["/world/cloud"])]
    assert len(clouds) == 1
    rec = np.frombuffer(clouds[0].data, dtype=[("p", "<f4", (3,)), ("c", "u1", (4,))])
    full = conv.cloud.points
    assert 0 < len(rec) <= len(full)
    sample = rec["p"][:: max(1, len(rec) // 200)].astype(np.float64)
    nearest = [np.sqrt(((full - p) ** 2).sum(axis=1).min()) for p in sample]
    assert max(nearest) < 1e-3


@pytest.mark.slow
def test_follow_ws_goes_on_after_the_server_goes_away_and_comes_back(tmp_path: Path) -> None:
    """The server stops halfway through the run and a new one starts on the same port:
    `follow ws://` reconnects, subscribes again and, having missed nothing (the publisher
    waited), ends on `convert`'s transform and octree; the report counts both losses."""
    log, out = tmp_path / "run.mcap", tmp_path / "out"
    assert run_cli(["slam2world", "simulate", "-o", str(log), "--reduced", "8", "--seed", "4"]) == 0
    with log.open("rb") as f:
        msgs = list(make_reader(f).iter_messages(log_time_order=True))
    sdk = _SdkServer(msgs)
    port = sdk.server.port
    url = f"ws://127.0.0.1:{port}"
    follow = [sys.executable, "-m", "slam2world.cli", "follow", url, "-o", str(out)]
    follow += ["--stable-hold", "0.3", "--idle-timeout", "4", "-q"]
    half = len(msgs) // 2
    with subprocess.Popen(follow, stderr=subprocess.PIPE, text=True) as proc:
        try:
            _wait_subscribed(sdk.listener)
            _publish(msgs[:half], sdk.channels)
            time.sleep(0.5)
            sdk.server.stop()
            time.sleep(1.0)
            sdk = _SdkServer(msgs, port)
            _wait_subscribed(sdk.listener)
            _publish(msgs[half:], sdk.channels)
            time.sleep(1.0)
            sdk.server.stop()
            assert proc.wait(timeout=60) == 0
            assert proc.stderr is not None
            assert proc.stderr.read().count("connection lost") == 2
        finally:
            sdk.server.stop()
            if proc.poll() is None:
                proc.kill()
    report = json.loads((out / "report.json").read_text())
    assert report["finished"] and report["disconnections"] == 2
    assert report["end"] == "server gone (2 connections lost)"
    conv = _ends_as_convert(log, out, tmp_path)
    assert report["keyframes"] == conv.report["keyframes"]


@pytest.mark.slow
def test_a_hostile_client_does_not_stop_the_server_serving_others(world: Path) -> None:
    """Malformed frames, a subscription to channels that do not exist, a flood of
    subscribes and a huge frame from one client: the server goes on, another client gets
    the world whole."""
    channels, messages = file_messages(world / "world.mcap")
    want = {t: len(m) for t, m in messages.items()}
    with sw.serve(world, port=0) as srv:
        with connect(srv.url, subprotocols=[SUBPROTOCOL], max_size=None) as bad:
            json.loads(bad.recv(timeout=10))
            subs = [{"id": i, "channelId": 10_000 + i} for i in range(10_000)]
            frames: list[str | bytes] = ["{not json", '{"op":"subscribe"}', '{"op":42}', "[]"]
            frames += [b"\x00\x01\x02", json.dumps({"op": "subscribe", "subscriptions": subs})]
            frames += [
                json.dumps({"op": "subscribe", "subscriptions": [{"id": i, "channelId": 1}]})
                for i in range(2000)
            ]
            frames.append(b"\x07" * (16 << 20))
            try:
                for f in frames:
                    bad.send(f)
            except ConnectionClosed:
                pass  # the server may close a client that breaks the protocol
            _, got = receive_world(srv.url, want)
            for topic, m in messages.items():
                assert got[topic] == m, topic
        assert srv.running
        _, got = receive_world(srv.url, want)
        assert got == messages


def test_a_client_that_reads_nothing_neither_holds_the_others_nor_the_stop(tmp_path: Path) -> None:
    """60 MB on one channel to a client that subscribes and never reads: another client still
    gets it all, and `stop()` returns within its 2 s wait."""
    from mcap.writer import Writer

    big = tmp_path / "big.mcap"
    with big.open("wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema(name="blob", encoding="jsonschema", data=b"{}")
        cid = w.register_channel(topic="/blob", message_encoding="json", schema_id=sid)
        for i in range(60):
            w.add_message(cid, log_time=i, data=b"[" + b"0," * (1 << 19) + b"0]", publish_time=i)
        w.finish()
    srv = sw.serve(big, port=0)
    host, port = "127.0.0.1", srv.port
    stalled = socket.create_connection((host, port))
    key = base64.b64encode(os.urandom(16)).decode()
    stalled.sendall(
        (
            f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
            f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
            f"Sec-WebSocket-Protocol: {SUBPROTOCOL}\r\n\r\n"
        ).encode()
    )
    stalled.settimeout(5)
    seen = b""
    while b'"topic"' not in seen:
        seen += stalled.recv(65536)
    channel = int(seen.split(b'"id":', 1)[1].split(b",", 1)[0])
    body = json.dumps(
        {"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channel}]}
    ).encode()
    mask = os.urandom(4)
    frame = bytes([0x81, 0x80 | 126]) + struct.pack(">H", len(body)) + mask
    stalled.sendall(frame + bytes(b ^ mask[i % 4] for i, b in enumerate(body)))
    try:
        _, got = receive_world(srv.url, {"/blob": 60})
        assert len(got["/blob"]) == 60
        t0 = time.monotonic()
        srv.stop()
        assert time.monotonic() - t0 < 10
    finally:
        stalled.close()
        srv.stop()
