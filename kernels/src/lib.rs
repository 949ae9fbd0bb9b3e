//! rtsim kernels.
