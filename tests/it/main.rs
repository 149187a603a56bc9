//! The integration tests, one module per concern, in one test binary: a change in
//! `src/` relinks this binary alone. `common` holds the helpers the modules share.
//!
//! Slow tests are `#[ignore = "slow: ..."]`: `make check` leaves them out, `make test`
//! runs them (`cargo test -- --include-ignored`).

mod common;

mod align;
mod align_dof;
mod align_options;
mod architecture;
mod beyond;
mod beyond_sim;
mod bounded;
mod bt_mutation;
mod cli_align;
mod cli_align_gnss;
mod cli_align_options;
mod cli_beyond;
mod cli_imu;
mod cloud;
mod colmap;
mod droid;
mod geo;
mod grid;
mod ground;
mod imu;
mod imu_sim;
mod mcap;
mod mutation;
mod octree;
mod octree_faults;
mod online;
mod pipeline;
mod read_log;
mod reconstruction;
mod report_html;
mod rosbag;
mod safety;
mod sim;
mod sim_cli;
mod stages;
mod trajectory;
mod trajectory_text;
