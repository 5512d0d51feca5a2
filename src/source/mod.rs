//! Sources: where samples come from. File input for the offline commands
//! (`input`), the gyro's binary frame decoder (`frame`) and capture reader
//! (`capture`), and the daemon's sources: the serial port (`serial`), replayed
//! captures (`replay`) and the simulated bench (`bench`).

pub mod bench;
pub mod capture;
pub mod frame;
pub mod input;
pub mod replay;
pub mod serial;
