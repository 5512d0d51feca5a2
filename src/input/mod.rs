//! Sources, the sans-IO part: file input for the offline commands (`input`),
//! the gyro's binary frames and their decoder (`frame`), and the capture
//! reader (`capture`). The daemon's async sources (serial port, replayed
//! captures, simulated bench) are in [`crate::daemon`]; nothing here imports
//! from `daemon`, `sink` or `model`.

pub mod capture;
pub mod frame;
pub mod plain;
