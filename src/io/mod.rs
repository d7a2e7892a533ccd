//! Files in and out: Siconos fc2d problems, JSON solve reports, simulation outputs (steps.csv,
//! summary.json, VTK time series, PNG pictures), grains files of a run's last state.

pub mod checkpoint;
pub mod grains;
#[cfg(feature = "plots")]
pub mod picture;
#[cfg(feature = "plots")]
pub mod plots;
pub mod punch_output;
pub mod report;
pub mod run_output;
pub mod siconos;
pub mod vtk;
