//! The files a conversion writes: `world.mcap` (Foxglove or ROS 2),
//! `cloud.ply`, `trajectory.txt`, `map.bt` (with an octree), the input's own
//! model (`model/`, a COLMAP model folder in the input's flavour) and
//! `report.json`.

use std::path::Path;
use std::time::Instant;

use crate::error::{Error, Result};
use crate::io::mcap::{write_world_mcap_with_octomap, WorldFlavor, WorldScene};
use crate::map::{OccupancyMap, VoxelState};

use super::native::NativeModel;
use super::report::{to_json_bytes, Report};
use super::Conversion;

/// The world cloud, both trajectories, `world → slam` and the occupied voxels.
pub const WORLD_MCAP: &str = "world.mcap";
/// The world cloud as binary PLY.
pub const CLOUD_PLY: &str = "cloud.ply";
/// The report.
pub const REPORT_JSON: &str = "report.json";
/// The occupancy octree (OctoMap binary), written when the conversion has one.
pub const MAP_BT: &str = "map.bt";
/// The SLAM poses in the world frame (`T_world_cam`), TUM format.
pub const TRAJECTORY_TUM: &str = "trajectory.txt";
/// The input's own model carried into the world frame (a COLMAP model
/// folder, same flavour), written when the input has one.
pub const COLMAP_MODEL: &str = "model";

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

    /// Writes the SLAM poses in the world frame (`T_world_cam`, the frames'
    /// stamps) as a TUM file, atomically.
    pub fn write_tum(&self, path: impl AsRef<Path>) -> Result<()> {
        crate::io::text::write_tum(&self.slam_trajectory, path)
    }

    /// Writes the input's own model in the world frame into the folder
    /// `path` (COLMAP: `format`, default the input's flavour). Error when the
    /// input had no model of its own.
    pub fn write_model(
        &self,
        path: impl AsRef<Path>,
        format: Option<crate::io::colmap::ColmapFormat>,
    ) -> Result<()> {
        match &self.native {
            Some(NativeModel::Colmap(m)) => m.write(path.as_ref(), format),
            None => Err(Error::invalid(
                "model",
                "the input has no model of its own to write (only COLMAP models have one)",
            )),
        }
    }

    /// Writes `world.mcap`, `cloud.ply`, `trajectory.txt`, `report.json`,
    /// with an octree `map.bt`, and with a model of the input's own `model/`
    /// into `dir` (created when missing), as one set: everything is written
    /// into a temporary folder inside `dir` first and moved under its final
    /// name once all is written (`report.json` last), so a failure leaves the
    /// previous outputs as they were; a `map.bt` or `model/` of an earlier
    /// run that this set does not have is removed with them. The written
    /// report carries the write time.
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
        let dir = dir.as_ref();
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let t = Instant::now();
        let stage = tempfile::Builder::new()
            .prefix(".slam2world-")
            .tempdir_in(dir)
            .map_err(|e| Error::io(dir, e))?;
        let s = stage.path();
        let mut names = vec![WORLD_MCAP, CLOUD_PLY, TRAJECTORY_TUM];
        self.write_world_mcap_with(s.join(WORLD_MCAP), flavor, octree)?;
        self.write_ply(s.join(CLOUD_PLY))?;
        self.write_tum(s.join(TRAJECTORY_TUM))?;
        if octree.is_some() {
            write_bt(octree, &s.join(MAP_BT))?;
            names.push(MAP_BT);
        }
        if self.native.is_some() {
            self.write_model(s.join(COLMAP_MODEL), None)?;
            names.push(COLMAP_MODEL);
        }
        let mut report = self.report.clone();
        report.timing.write_s = t.elapsed().as_secs_f64();
        write_report(&report, &s.join(REPORT_JSON))?;
        names.push(REPORT_JSON);
        // Stale outputs of an earlier run that this set does not have.
        let stale = [MAP_BT, COLMAP_MODEL]
            .into_iter()
            .filter(|n| !names.contains(n));
        for name in stale.chain(names.iter().copied()) {
            let dst = dir.join(name);
            if dst.is_dir() || (dst.exists() && !s.join(name).exists()) {
                // Moved into the stage, removed with it.
                let old = s.join(format!(".old-{name}"));
                std::fs::rename(&dst, &old).map_err(|e| Error::io(&dst, e))?;
            }
            let src = s.join(name);
            if src.exists() {
                std::fs::rename(&src, &dst).map_err(|e| Error::io(&dst, e))?;
            }
        }
        stage.close().map_err(|e| Error::io(dir, e))
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
