"""Writes `layout.json` beside this file: the Foxglove layout of slam2world's world, built with
the Foxglove SDK's layout API (`foxglove.layouts`, PyPI `foxglove-sdk`).

A 3-D panel in the `world` frame (the metric cloud, the SLAM and reference paths, the
occupied voxels, the 2-D grid), the session's state as `follow` reports it, and a plot of its
fit and latency. The same layout works on `world.mcap`, `slam2world serve`, `follow --serve`
and `Session.serve`: the topics are the same. `slam2world layout` writes it out (it is compiled
into the binary); `tests/python/test_live.py` checks that this script still gives it.

    python src/live/layout.py      # after a change here
"""

from __future__ import annotations

import json
from pathlib import Path

import foxglove.layouts as fl

STATE = "/slam2world/state"


def layout() -> fl.Layout:
    """The layout."""
    scene = fl.ThreeDeePanel(
        title="Metric world",
        config=fl.ThreeDeeConfig(
            follow_tf="world",
            topics={
                "/world/cloud": fl.BaseRendererPointCloudTopicSettings(
                    visible=True, point_size=2, color_mode="rgba-fields"
                ),
                "/world/slam_trajectory": fl.BaseRendererPosesTopicSettings(
                    visible=True, type="line", line_width=0.05, gradient=("#ff6b00", "#ffd000")
                ),
                "/world/reference": fl.BaseRendererPosesTopicSettings(
                    visible=True, type="line", line_width=0.03, gradient=("#1f77b4", "#17becf")
                ),
                "/slam2world/octomap": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                "/slam2world/grid": fl.BaseRendererGridTopicSettings(
                    visible=True, explicit_alpha=0.6
                ),
            },
            layers={"grid": fl.BaseRendererGridLayerSettings(visible=True, size=50, divisions=50)},
        ),
    )
    state = fl.RawMessagesPanel(
        title="Session state",
        config=fl.RawMessagesConfig(topic_path=STATE, expansion="all"),
    )
    fit = fl.PlotPanel(
        title="Fit and latency",
        config=fl.PlotConfig(
            paths=[
                fl.PlotSeries(value=f"{STATE}.fit_rmse", label="fit rmse (m)"),
                fl.PlotSeries(value=f"{STATE}.latency_s", label="latency (s)"),
            ]
        ),
    )
    side = fl.SplitContainer(
        direction="column",
        items=[fl.SplitItem(proportion=2, content=state), fl.SplitItem(content=fit)],
    )
    return fl.Layout(
        content=fl.SplitContainer(
            direction="row",
            items=[fl.SplitItem(proportion=3, content=scene), fl.SplitItem(content=side)],
        )
    )


def layout_json() -> str:
    """The layout as `layout.json` holds it (indented, one trailing newline)."""
    return json.dumps(json.loads(layout().to_json()), indent=2) + "\n"


if __name__ == "__main__":
    out = Path(__file__).with_name("layout.json")
    out.write_text(layout_json())
    print(f"wrote {out}")
