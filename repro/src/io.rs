//! Output: files written whole or not at all, reports printed and written,
//! figure paths.

use crate::options::ReproduceArgs;
use crate::report::Report;
use crate::{AppError, AppResult};
use std::path::{Path, PathBuf};

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

/// Where a figure's PNG goes: `--out DIR`, else the current directory.
pub fn png_path(a: &ReproduceArgs, name: &str) -> AppResult<PathBuf> {
    let dir = a.out.clone().unwrap_or_else(|| PathBuf::from("."));
    std::fs::create_dir_all(&dir).map_err(|e| AppError(format!("{}: {e}", dir.display())))?;
    Ok(dir.join(format!("{name}.png")))
}

/// Print a report (and with `--out`, write it to DIR/NAME.ext); an error if
/// `bad` rays differed from the reference.
pub fn emit(a: &ReproduceArgs, name: &str, rep: &Report, bad: f64) -> AppResult<()> {
    let text = rep.render(a.format);
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir).map_err(|e| AppError(format!("{}: {e}", dir.display())))?;
        let ext = a.format.ext();
        write_atomic(&dir.join(format!("{name}.{ext}")), text.as_bytes())?;
    }
    print!("{text}");
    if bad > 0.0 {
        return Err(AppError(format!("{bad} rays differ from the reference")));
    }
    Ok(())
}
