//! Files in and out: Siconos fc2d problems, JSON solve reports, simulation outputs (steps.csv,
//! summary.json, VTK time series, PNG pictures).

pub mod checkpoint;
#[cfg(feature = "plots")]
pub mod picture;
#[cfg(feature = "plots")]
pub mod plots;
pub mod punch_output;
pub mod report;
pub mod run_output;
pub mod siconos;
pub mod vtk;
