//! Files written whole or not at all.

use crate::{AppError, AppResult};
use std::path::Path;

/// Write a file whole or not at all: a temporary beside it, then a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> AppResult<()> {
    let name = path
        .file_name()
        .ok_or_else(|| AppError(format!("{}: not a file name", path.display())))?;
    let tmp = path.with_file_name(format!(
        ".{}.tmp-{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    let r = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    if let Err(e) = r {
        let _ = std::fs::remove_file(&tmp);
        return Err(AppError(format!("{}: {e}", path.display())));
    }
    Ok(())
}
