//! The app's end-to-end tests, one module per concern, in one test binary
//! (one link of everything the app depends on, not one per file).

mod cli;
mod common;
mod layout;
mod machines;
mod scenes;
mod volume_cli;
