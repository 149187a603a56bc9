//! Everything `convert` can be told, checked once before any input is read.

use crate::align::trajectories::TrajectoryAlignOptions;
use crate::align::windowed::Window;
use crate::cloud::PointFilter;
use crate::defaults;
use crate::error::{Error, Result};
use crate::imu::ImuInitOptions;
use crate::io::log::ReadOptions;
use crate::map::{GridParams, MapParams};

use super::gnss::{GeoOutputs, GnssOptions};
use super::prior::PriorOptions;

/// Everything `convert` can be told.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvertOptions {
    /// Topics to read (found by schema when `None`).
    pub read: ReadOptions,
    /// Association and fit: `max_diff`, `offset` (added to the SLAM stamps),
    /// `n_to_align`, scale, start-up cut, robust fit, orientations, time
    /// offset, extrinsic.
    pub align: TrajectoryAlignOptions,
    /// Which pixels become points (the LSD-SLAM viewer's defaults by default).
    pub filter: PointFilter,
    /// Also fit a windowed (drift-aware) alignment and compare it with the
    /// single Sim(3) in the report.
    pub compare_windowed: Option<Window>,
    /// Carry each keyframe (its points, camera centre and world pose) with the
    /// windowed alignment at its time instead of the single Sim(3); needs
    /// `compare_windowed` (the window). The report's `t_world_slam` stays the
    /// single fit.
    pub windowed_cloud: bool,
    /// Inertial initialisation, used when the input has raw IMU samples: for
    /// `T_world_slam` without reference poses, as a consistency check with them.
    pub imu: ImuInitOptions,
    /// The occupancy octree built from the world cloud (every OctoMap
    /// parameter); `None` builds none.
    pub map: Option<MapParams>,
    /// The 2-D occupancy grid projected from the octree (`map.pgm`,
    /// `map.yaml`, `map_height.npy`, a grid channel in `world.mcap`); needs
    /// `map`. `None` projects none.
    pub grid: Option<GridParams>,
    /// Confidence level of the report's intervals.
    pub confidence: f64,
    /// How GNSS fixes become the reference (used when the recording has fixes).
    pub gnss: GnssOptions,
    /// The georeferenced clouds written beside the others.
    pub geo_outputs: GeoOutputs,
    /// Metric scale and "up" with no second sensor (a camera height, a known
    /// distance, planar motion): `T_world_slam` when the recording has no
    /// reference sensor, else compared with it.
    pub prior: Option<PriorOptions>,
}

impl Default for ConvertOptions {
    fn default() -> Self {
        ConvertOptions {
            read: ReadOptions::default(),
            align: TrajectoryAlignOptions::default(),
            filter: PointFilter::default(),
            compare_windowed: None,
            windowed_cloud: false,
            imu: ImuInitOptions::default(),
            map: None,
            grid: None,
            confidence: defaults::CONFIDENCE,
            gnss: GnssOptions::default(),
            geo_outputs: GeoOutputs::default(),
            prior: None,
        }
    }
}

impl ConvertOptions {
    /// Checks every option that does not depend on the input: the fit's, the
    /// filter's, the octree's, the IMU's, the confidence level, and that
    /// `windowed_cloud` has its window.
    pub fn check(&self) -> Result<()> {
        self.align.check()?;
        self.gnss.check()?;
        self.filter.validate()?;
        self.imu.validate()?;
        if let Some(map) = &self.map {
            map.check()?;
        }
        if let Some(grid) = &self.grid {
            grid.check()?;
            if self.map.is_none() {
                return Err(Error::invalid(
                    "grid",
                    "the 2-D grid is projected from the octree: give an octree resolution too",
                ));
            }
        }
        if !(self.confidence > 0.0 && self.confidence < 1.0) {
            return Err(Error::invalid(
                "confidence",
                format!("must be in (0, 1), got {}", self.confidence),
            ));
        }
        if self.windowed_cloud && self.compare_windowed.is_none() {
            return Err(Error::invalid(
                "windowed_cloud",
                "needs the window of the windowed alignment (compare_windowed)",
            ));
        }
        if let Some(w) = self.compare_windowed {
            w.check()?;
        }
        if let Some(p) = &self.prior {
            p.check()?;
        }
        Ok(())
    }
}
