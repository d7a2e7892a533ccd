//! Files in and out: Siconos fc2d problems, JSON solve reports.

pub mod report;
pub mod siconos;
