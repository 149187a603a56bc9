//! The files a conversion writes: `world.mcap` (Foxglove or ROS 2),
//! `cloud.ply`, `map.bt` (with an octree), `report.json` and `report.html`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::{Error, Result};
use crate::io::mcap::{write_world_mcap_with_octomap, WorldFlavor, WorldScene};
use crate::map::{OccupancyMap, VoxelState};

use super::figures::{FigureData, FigureOptions};
use super::html::{write_html, Page, Summary};
use super::report::{to_json_bytes, DemoReport, Report};
use super::Conversion;

/// The world cloud, both trajectories, `world → slam` and the occupied voxels.
pub const WORLD_MCAP: &str = "world.mcap";
/// The world cloud as binary PLY.
pub const CLOUD_PLY: &str = "cloud.ply";
/// The report.
pub const REPORT_JSON: &str = "report.json";
/// The occupancy octree (OctoMap binary), written when the conversion has one.
pub const MAP_BT: &str = "map.bt";
/// The report page (self-contained HTML: summary, paths, errors, cloud, voxels).
pub const REPORT_HTML: &str = "report.html";

/// What `report.html` adds to the conversion: the demo's comparison with the
/// truth, and the limits of what it embeds.
#[derive(Clone, Copy, Debug, Default)]
pub struct HtmlOptions<'a> {
    /// The demo report (its truth card), for `demo`.
    pub demo: Option<&'a DemoReport>,
    /// Limits of the embedded cloud and voxels.
    pub figures: FigureOptions,
}

impl Conversion {
    /// Writes `world.mcap` (cloud, both trajectories, `world → slam`, and the
    /// occupied voxels of `octree` when given).
    pub fn write_world_mcap_with(
        &self,
        path: impl AsRef<Path>,
        flavor: WorldFlavor,
        octree: Option<&OccupancyMap>,
    ) -> Result<()> {
        let stamp = self
            .slam_trajectory
            .timestamps
            .last()
            .copied()
            .unwrap_or(0.0)
            .max(0.0);
        let scene = WorldScene {
            points: &self.cloud.points,
            colors: self.cloud.colors.as_deref(),
            t_world_slam: self.transform(),
            slam_trajectory: Some(&self.slam_trajectory),
            reference: self.reference.as_ref(),
            stamp,
            world_frame: "world",
            slam_frame: "slam",
        };
        let leaves = octree.map(|m| m.leaves(VoxelState::Occupied));
        write_world_mcap_with_octomap(path, &scene, leaves.as_deref(), flavor)
    }

    /// Writes `world.mcap` with the conversion's own octree.
    pub fn write_world_mcap(&self, path: impl AsRef<Path>, flavor: WorldFlavor) -> Result<()> {
        self.write_world_mcap_with(path, flavor, self.octree.as_ref())
    }

    /// Writes the octree as an OctoMap `.bt` file (through a temporary file,
    /// renamed). Error when the conversion has no octree.
    pub fn write_bt(&self, path: impl AsRef<Path>) -> Result<()> {
        write_bt(self.octree.as_ref(), path.as_ref())
    }

    /// Writes the world cloud as binary PLY.
    pub fn write_ply(&self, path: impl AsRef<Path>) -> Result<()> {
        crate::io::ply::write_ply(path, &self.cloud)
    }

    /// Writes `report.json` (through a temporary file, renamed).
    pub fn write_report(&self, path: impl AsRef<Path>) -> Result<()> {
        write_report(&self.report, path.as_ref())
    }

    /// Writes `report.html` with `octree`'s voxels (through a temporary file,
    /// renamed).
    pub fn write_html_with(
        &self,
        path: impl AsRef<Path>,
        octree: Option<&OccupancyMap>,
        opts: &HtmlOptions<'_>,
    ) -> Result<()> {
        self.write_page(&self.report, path.as_ref(), octree, opts)
    }

    fn write_page(
        &self,
        report: &Report,
        path: &Path,
        octree: Option<&OccupancyMap>,
        opts: &HtmlOptions<'_>,
    ) -> Result<()> {
        let figures = FigureData::of_conversion(self, octree, &opts.figures)?;
        let title = report.input.display().to_string();
        let page = Page {
            title: &title,
            summary: Summary::Convert(report),
            demo: opts.demo,
            figures: &figures,
        };
        write_html(path, &page)
    }

    /// Writes `world.mcap`, `cloud.ply`, `report.json`, `report.html` and,
    /// with an octree, `map.bt` into `dir` (created when missing); the written
    /// report (in both files the same) carries the write time. When one
    /// fails, the outputs written by this call are removed.
    pub fn write_all(&self, dir: impl AsRef<Path>, flavor: WorldFlavor) -> Result<()> {
        self.write_all_with(dir, flavor, self.octree.as_ref())
    }

    /// [`Conversion::write_all`] with `octree` in place of the conversion's own
    /// (the Python binding keeps the octree in its own object).
    pub fn write_all_with(
        &self,
        dir: impl AsRef<Path>,
        flavor: WorldFlavor,
        octree: Option<&OccupancyMap>,
    ) -> Result<()> {
        self.write_all_html(dir, flavor, octree, &HtmlOptions::default())
    }

    /// [`Conversion::write_all_with`] with what `report.html` adds.
    pub fn write_all_html(
        &self,
        dir: impl AsRef<Path>,
        flavor: WorldFlavor,
        octree: Option<&OccupancyMap>,
        html: &HtmlOptions<'_>,
    ) -> Result<()> {
        let dir = dir.as_ref();
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let t = Instant::now();
        let mut written: Vec<PathBuf> = Vec::new();
        let result = (|| {
            let p = dir.join(WORLD_MCAP);
            self.write_world_mcap_with(&p, flavor, octree)?;
            written.push(p);
            let p = dir.join(CLOUD_PLY);
            self.write_ply(&p)?;
            written.push(p);
            if octree.is_some() {
                let p = dir.join(MAP_BT);
                write_bt(octree, &p)?;
                written.push(p);
            }
            let mut report = self.report.clone();
            report.timing.write_s = t.elapsed().as_secs_f64();
            let p = dir.join(REPORT_HTML);
            self.write_page(&report, &p, octree, html)?;
            written.push(p);
            let p = dir.join(REPORT_JSON);
            write_report(&report, &p)?;
            written.push(p);
            Ok(())
        })();
        if result.is_err() {
            for p in &written {
                let _ = std::fs::remove_file(p);
            }
        }
        result
    }
}

/// Writes `octree` as `.bt`; an error without one.
pub fn write_bt(octree: Option<&OccupancyMap>, path: &Path) -> Result<()> {
    match octree {
        Some(m) => m.write_bt(path),
        None => Err(Error::invalid(
            "octree",
            "the conversion has no octree (convert with an octree resolution)",
        )),
    }
}

/// Writes a report as pretty JSON, atomically.
pub fn write_report(report: &Report, path: &Path) -> Result<()> {
    crate::io::atomic::write_bytes_atomic(path, &to_json_bytes(report)?)
}
