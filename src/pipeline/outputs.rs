//! The files a conversion writes: `world.mcap` (Foxglove or ROS 2),
//! `cloud.ply`, `trajectory.txt`, `map.bt` (with an octree), the input's own
//! model (`model/`, a COLMAP model folder in the input's flavour), with a
//! GNSS reference `cloud.las` / `cloud.laz` (the UTM zone or ECEF) and, when
//! asked, `cloud.pcd`,
//! `report.json` and `report.html`, as one [`OutputSet`]: all written under
//! temporary names, then published together, the names of [`OUTPUT_NAMES`]
//! this run did not write removed; never over an input of the run.

use std::path::Path;
use std::time::Instant;

use crate::error::{Error, Result};
use crate::geo::GeoCrs;
use crate::io::atomic::{Committed, OutputSet};
use crate::io::las::{las_cloud_into, LasInfo};
use crate::io::mcap::grid_msgs::{grid_channels, GridChannel};
use crate::io::mcap::write::{write_world_mcap_extra_into, ExtraChannel};
use crate::io::mcap::{WorldFlavor, WorldScene};
use crate::io::nav2::{write_nav2_into, Nav2Files};
use crate::io::pcd::write_pcd_cloud_into;
use crate::map::{OccupancyMap, VoxelState};

use super::figures::{FigureData, FigureOptions};
use super::html::{write_html_into, Page, Summary};
use super::native::NativeModel;
use super::report::{to_json_bytes, DemoReport, GeoOutputReport, Report};
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
/// The georeferenced world cloud, LAS 1.4 with its CRS (UTM zone or ECEF):
/// written with a GNSS reference.
pub const CLOUD_LAS: &str = "cloud.las";
/// [`CLOUD_LAS`] compressed (LAZ), when asked for.
pub const CLOUD_LAZ: &str = "cloud.laz";
/// The world cloud as binary PCD (PCL), when asked for.
pub const CLOUD_PCD: &str = "cloud.pcd";
/// The 2-D occupancy grid as nav2 `map_server` reads it (trinary PGM),
/// written with a grid.
pub const MAP_PGM: &str = "map.pgm";
/// The `map_server` metadata of [`MAP_PGM`].
pub const MAP_YAML: &str = "map.yaml";
/// The height of the highest occupied voxel per cell of [`MAP_PGM`] (NumPy).
pub const MAP_HEIGHT_NPY: &str = "map_height.npy";

/// What `report.html` adds to the conversion: the demo's comparison with the
/// truth, and the limits of what it embeds.
#[derive(Clone, Copy, Debug, Default)]
pub struct HtmlOptions<'a> {
    /// The demo report (its truth card), for `demo`.
    pub demo: Option<&'a DemoReport>,
    /// Limits of the embedded cloud and voxels.
    pub figures: FigureOptions,
}
/// The SLAM poses in the world frame (`T_world_cam`), TUM format.
pub const TRAJECTORY_TUM: &str = "trajectory.txt";
/// The input's own model carried into the world frame (a COLMAP model
/// folder, same flavour), written when the input has one.
pub const COLMAP_MODEL: &str = "model";

/// Every name a conversion may write into its output folder. A writer that
/// adds an output adds its name here: a later run that does not produce it
/// removes the stale one.
/// (`model/…`: the files of a COLMAP model of either flavour.)
pub const OUTPUT_NAMES: &[&str] = &[
    WORLD_MCAP,
    CLOUD_PLY,
    TRAJECTORY_TUM,
    MAP_BT,
    REPORT_JSON,
    REPORT_HTML,
    CLOUD_LAS,
    CLOUD_LAZ,
    CLOUD_PCD,
    MAP_PGM,
    MAP_YAML,
    MAP_HEIGHT_NPY,
    "model/cameras.bin",
    "model/rigs.bin",
    "model/frames.bin",
    "model/images.bin",
    "model/points3D.bin",
    "model/cameras.txt",
    "model/rigs.txt",
    "model/frames.txt",
    "model/images.txt",
    "model/points3D.txt",
];

/// The output set of a conversion in `dir`: the names of [`OUTPUT_NAMES`],
/// none of which may be one of `inputs` (the log, the reference, the cloud).
/// Make it before the conversion to refuse a bad output folder before the work.
pub fn output_set<P: AsRef<Path>>(
    dir: &Path,
    inputs: impl IntoIterator<Item = P>,
) -> Result<OutputSet> {
    let set = OutputSet::folder(dir, OUTPUT_NAMES)?.with_inputs(inputs);
    for name in OUTPUT_NAMES {
        set.check_output(&dir.join(name))?;
    }
    Ok(set)
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
        let mut set = OutputSet::new().with_inputs([&self.report.input]);
        self.world_mcap_into(&mut set, path.as_ref(), flavor, octree)?;
        set.commit().map(|_| ())
    }

    /// The last SLAM stamp, the time of the messages of `world.mcap`;
    /// refused (naming the keyframe) where an MCAP log time cannot hold it.
    fn world_stamp(&self) -> Result<f64> {
        let stamp = self
            .slam_trajectory
            .timestamps
            .last()
            .copied()
            .unwrap_or(0.0)
            .max(0.0);
        if stamp >= 1.8e10 {
            let id = self.report.pairs.last().map(|p| p.keyframe_id);
            return Err(Error::invalid(
                "keyframe time",
                format!(
                    "the last SLAM stamp{} of {} is {} s, beyond what an MCAP log time holds (1.8e10 s); world.mcap not written",
                    id.map_or(String::new(), |id| format!(" (keyframe {id})")),
                    self.report.input.display(),
                    crate::error::num(stamp)
                ),
            ));
        }
        Ok(stamp)
    }

    fn world_mcap_into(
        &self,
        set: &mut OutputSet,
        path: &Path,
        flavor: WorldFlavor,
        octree: Option<&OccupancyMap>,
    ) -> Result<()> {
        let scene = WorldScene {
            cloud: self.cloud_ref(),
            t_world_slam: self.transform(),
            slam_trajectory: Some(&self.slam_trajectory),
            reference: self.reference_ref(),
            stamp: self.world_stamp()?,
            world_frame: "world",
            slam_frame: "slam",
            frames: &[],
        };
        let leaves = octree.map(|m| m.leaves(VoxelState::Occupied));
        let channels = match &self.grid {
            Some((g, _)) => grid_channels(g, scene.stamp, scene.world_frame, flavor)?,
            None => Vec::new(),
        };
        let extra: Vec<ExtraChannel<'_>> = channels.iter().map(GridChannel::as_extra).collect();
        write_world_mcap_extra_into(set, path, &scene, leaves.as_deref(), &extra, flavor, true)
    }

    /// Writes `world.mcap` with the conversion's own octree.
    pub fn write_world_mcap(&self, path: impl AsRef<Path>, flavor: WorldFlavor) -> Result<()> {
        self.write_world_mcap_with(path, flavor, self.octree.as_ref())
    }

    /// Writes the octree as an OctoMap `.bt` file (through a temporary file,
    /// renamed). Error when the conversion has no octree.
    pub fn write_bt(&self, path: impl AsRef<Path>) -> Result<()> {
        let mut set = OutputSet::new().with_inputs([&self.report.input]);
        write_bt_into(&mut set, self.octree.as_ref(), path.as_ref())?;
        set.commit().map(|_| ())
    }

    /// Writes the world cloud as binary PLY.
    pub fn write_ply(&self, path: impl AsRef<Path>) -> Result<()> {
        let mut set = OutputSet::new().with_inputs([&self.report.input]);
        self.ply_into(&mut set, path.as_ref())?;
        set.commit().map(|_| ())
    }

    /// The world cloud as binary PLY, one output of `set`.
    pub fn ply_into(&self, set: &mut OutputSet, path: &Path) -> Result<()> {
        crate::io::ply::write_ply_cloud_into(set, path, self.cloud_ref())
    }

    /// Writes `report.json` (through a temporary file, renamed).
    pub fn write_report(&self, path: impl AsRef<Path>) -> Result<()> {
        let mut set = OutputSet::new().with_inputs([&self.report.input]);
        set.write_bytes(path.as_ref(), &to_json_bytes(&self.report)?)?;
        set.commit().map(|_| ())
    }

    /// Writes `report.html` with `octree`'s voxels (through a temporary file,
    /// renamed).
    pub fn write_html_with(
        &self,
        path: impl AsRef<Path>,
        octree: Option<&OccupancyMap>,
        opts: &HtmlOptions<'_>,
    ) -> Result<()> {
        let mut set = OutputSet::new().with_inputs([&self.report.input]);
        self.page_into(&mut set, path.as_ref(), &self.report, octree, opts)?;
        set.commit().map(|_| ())
    }

    /// Writes `report.html` summarising `report` to `path`, one output of `set`.
    fn page_into(
        &self,
        set: &mut OutputSet,
        path: &Path,
        report: &Report,
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
        write_html_into(set, path, &page)
    }

    /// Writes the SLAM poses in the world frame (`T_world_cam`, the frames'
    /// stamps) as a TUM file, atomically.
    pub fn write_tum(&self, path: impl AsRef<Path>) -> Result<()> {
        let mut set = OutputSet::new().with_inputs([&self.report.input]);
        let path = path.as_ref();
        set.write_bytes(path, &crate::io::text::tum_bytes(&self.slam_trajectory)?)?;
        set.commit().map(|_| ())
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

    /// Writes `world.mcap`, `cloud.ply`, `trajectory.txt`, `report.json`, `report.html`,
    /// with an octree `map.bt`, and with a model of the input's own `model/`
    /// into `dir` (created when missing); the written report carries the
    /// write time. All or nothing: when one fails (or the run is
    /// interrupted), the previous outputs in `dir` stay as they were; on
    /// success, a `map.bt` or `model/` file of an earlier run that this one
    /// does not produce is removed. Never writes over the conversion's input.
    pub fn write_all(&self, dir: impl AsRef<Path>, flavor: WorldFlavor) -> Result<Committed> {
        self.write_all_with(dir, flavor, self.octree.as_ref())
    }

    /// [`Conversion::write_all`] with `octree` in place of the conversion's own
    /// (the Python binding keeps the octree in its own object).
    pub fn write_all_with(
        &self,
        dir: impl AsRef<Path>,
        flavor: WorldFlavor,
        octree: Option<&OccupancyMap>,
    ) -> Result<Committed> {
        self.write_all_html(dir, flavor, octree, &HtmlOptions::default())
    }

    /// [`Conversion::write_all_with`] with what `report.html` adds.
    pub fn write_all_html(
        &self,
        dir: impl AsRef<Path>,
        flavor: WorldFlavor,
        octree: Option<&OccupancyMap>,
        html: &HtmlOptions<'_>,
    ) -> Result<Committed> {
        let mut set = output_set(dir.as_ref(), [&self.report.input])?;
        self.write_into_html(&mut set, flavor, octree, html)?;
        set.commit()
    }

    /// Writes every output of the conversion into the folder of `set`
    /// ([`output_set`]), to be published by [`OutputSet::commit`].
    pub fn write_into(
        &self,
        set: &mut OutputSet,
        flavor: WorldFlavor,
        octree: Option<&OccupancyMap>,
    ) -> Result<()> {
        self.write_into_html(set, flavor, octree, &HtmlOptions::default())
    }

    /// [`Conversion::write_into`] with what `report.html` adds.
    pub fn write_into_html(
        &self,
        set: &mut OutputSet,
        flavor: WorldFlavor,
        octree: Option<&OccupancyMap>,
        html: &HtmlOptions<'_>,
    ) -> Result<()> {
        let t = Instant::now();
        let [world, cloud, tum, bt, json, page] = [
            WORLD_MCAP,
            CLOUD_PLY,
            TRAJECTORY_TUM,
            MAP_BT,
            REPORT_JSON,
            REPORT_HTML,
        ]
        .map(|n| set.path(n));
        self.world_mcap_into(set, &world, flavor, octree)?;
        self.ply_into(set, &cloud)?;
        set.write_bytes(&tum, &crate::io::text::tum_bytes(&self.slam_trajectory)?)?;
        if octree.is_some() {
            write_bt_into(set, octree, &bt)?;
        }
        if let Some((grid, params)) = &self.grid {
            let files = Nav2Files {
                image: set.path(MAP_PGM),
                yaml: set.path(MAP_YAML),
                height: set.path(MAP_HEIGHT_NPY),
            };
            write_nav2_into(set, grid, &files, params.occupied_threshold)?;
        }
        if let Some(NativeModel::Colmap(m)) = &self.native {
            let dir = set.path(COLMAP_MODEL);
            std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
            for (stem, bytes) in m.encode(&dir, m.format)? {
                let name = format!("{COLMAP_MODEL}/{stem}.{}", m.format.extension());
                set.write_bytes(&set.path(&name), &bytes)?;
            }
        }
        let mut report = self.report.clone();
        self.geo_clouds_into(set, &mut report)?;
        report.timing.write_s = t.elapsed().as_secs_f64();
        self.page_into(set, &page, &report, octree, html)?;
        set.write_bytes(&json, &to_json_bytes(&report)?)
    }
}

impl Conversion {
    /// The georeferenced clouds the conversion asks for (`cloud.las` /
    /// `cloud.laz` in the CRS of [`super::gnss::GeoOutputs::crs`], `cloud.pcd` in the
    /// world frame), named in `report.gnss.outputs`.
    fn geo_clouds_into(&self, set: &mut OutputSet, report: &mut Report) -> Result<()> {
        let geo = &self.geo_outputs;
        if let (Some(frame), true) = (&self.enu, geo.las_for(self.enu.is_some())?) {
            let name = if geo.laz { CLOUD_LAZ } else { CLOUD_LAS };
            let path = set.path(name);
            let info = self.las_into(set, &path, &frame.origin(), geo.crs, geo.laz)?;
            if let Some(g) = report.gnss.as_mut() {
                g.outputs.push(GeoOutputReport {
                    name: name.into(),
                    epsg: Some(info.epsg),
                    offset: Some(info.offset),
                });
            }
        }
        if geo.pcd {
            write_pcd_cloud_into(set, &set.path(CLOUD_PCD), self.cloud_ref())?;
            if let Some(g) = report.gnss.as_mut() {
                g.outputs.push(GeoOutputReport {
                    name: CLOUD_PCD.into(),
                    epsg: None,
                    offset: None,
                });
            }
        }
        Ok(())
    }

    /// Writes the world cloud as LAS 1.4 (LAZ when `path` ends in `.laz`) in
    /// `crs` (default: the UTM zone of the ENU origin); an error without a
    /// GNSS reference.
    pub fn write_las(&self, path: impl AsRef<Path>, crs: Option<GeoCrs>) -> Result<LasInfo> {
        let Some(frame) = &self.enu else {
            return Err(Error::invalid(
                "las",
                "a LAS file carries a CRS: it needs a GNSS reference (a gnss topic or file)",
            ));
        };
        let path = path.as_ref();
        let compressed = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("laz"));
        let mut set = OutputSet::new().with_inputs([&self.report.input]);
        let crs = crs.unwrap_or(self.geo_outputs.crs);
        let info = self.las_into(&mut set, path, &frame.origin(), crs, compressed)?;
        set.commit()?;
        Ok(info)
    }

    /// The world cloud as LAS (LAZ when `compressed`), one output of `set`.
    fn las_into(
        &self,
        set: &mut OutputSet,
        path: &Path,
        origin: &crate::geo::Geodetic,
        crs: GeoCrs,
        compressed: bool,
    ) -> Result<LasInfo> {
        let mut info = None;
        set.write(path, |file| {
            let file = file.try_clone().map_err(|e| Error::io(path, e))?;
            let w = std::io::BufWriter::with_capacity(1 << 20, file);
            let (mut w, i) = las_cloud_into(w, path, self.cloud_ref(), origin, crs, compressed)?;
            info = Some(i);
            std::io::Write::flush(&mut w).map_err(|e| Error::io(path, e))
        })?;
        info.ok_or_else(|| Error::invalid("las", "no LAS was written"))
    }

    /// Writes the world cloud as binary PCD (world-frame `f32` metres).
    pub fn write_pcd(&self, path: impl AsRef<Path>) -> Result<()> {
        let mut set = OutputSet::new().with_inputs([&self.report.input]);
        write_pcd_cloud_into(&mut set, path.as_ref(), self.cloud_ref())?;
        set.commit().map(|_| ())
    }
}

/// Writes `octree` as `.bt`; an error without one.
pub fn write_bt(octree: Option<&OccupancyMap>, path: &Path) -> Result<()> {
    let mut set = OutputSet::new();
    write_bt_into(&mut set, octree, path)?;
    set.commit().map(|_| ())
}

/// `octree` as `.bt`, one output of `set`; an error without one.
pub fn write_bt_into(
    set: &mut OutputSet,
    octree: Option<&OccupancyMap>,
    path: &Path,
) -> Result<()> {
    match octree {
        Some(m) => set.write_bytes(path, &m.to_bt_bytes()),
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
