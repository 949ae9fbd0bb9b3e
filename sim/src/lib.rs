//! rtsim timing model (issue 3).
