//! Geometry: Sim(3) transforms, quaternion/matrix conversions, the pinhole camera.

mod camera;
mod sim3;

pub use camera::PinholeCamera;
pub use sim3::{rotation_from_matrix, unit_quaternion_xyzw, PointScalar, Sim3};
