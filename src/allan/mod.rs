//! Allan statistics: batch estimators (OADEV, ADEV, MDEV, OHDEV, TOTDEV) with
//! equivalent degrees of freedom and chi-square confidence intervals, and the
//! streaming octave-spaced accumulators used by the daemon.

pub mod streaming;
