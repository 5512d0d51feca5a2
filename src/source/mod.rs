//! Sources: where samples come from. File input for the offline commands
//! (`input`), the gyro's binary frame decoder (`frame`), and (in the daemon)
//! serial ports and replayed captures.

pub mod capture;
pub mod frame;
pub mod input;
