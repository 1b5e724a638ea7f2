//! Safe output paths: what may be replaced, when two paths name one file, and the temporary
//! files a write is using (so that an abort can remove them).

use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use crate::error::{Error, Result};

/// Temporary files being written now.
static PARTIALS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Numbers the temporary files of this process.
static NEXT: AtomicU64 = AtomicU64::new(0);

/// Refuses to write to `path` unless it is absent or a regular file: a symbolic link, a
/// directory, a device node (`/dev/null`, `/dev/full`), a FIFO or a socket is left alone.
pub fn check_target(path: &Path) -> Result<()> {
    let what = match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(Error::io(path.display(), e)),
        Ok(m) => {
            let t = m.file_type();
            if t.is_file() {
                return Ok(());
            } else if t.is_symlink() {
                "a symbolic link"
            } else if t.is_dir() {
                "a directory"
            } else {
                special_kind(&t)
            }
        }
    };
    Err(Error::Output(format!(
        "{}: is {what}; outputs are written only as regular files (give another path)",
        path.display()
    )))
}

#[cfg(unix)]
fn special_kind(t: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if t.is_char_device() || t.is_block_device() {
        "a device"
    } else if t.is_fifo() {
        "a FIFO"
    } else if t.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    }
}

#[cfg(not(unix))]
fn special_kind(_: &std::fs::FileType) -> &'static str {
    "not a regular file"
}

/// What names one file: its normalised absolute path (symbolic links of existing
/// directories resolved, `.` and `..` applied), and its (device, inode) where it exists.
#[derive(Clone, Debug)]
pub struct FileId {
    path: PathBuf,
    inode: Option<(u64, u64)>,
}

impl FileId {
    /// The identity of `path` (which need not exist yet).
    pub fn of(path: &Path) -> Result<FileId> {
        let io = |e: std::io::Error| Error::io(path.display(), e);
        let abs = std::env::current_dir().map_err(io)?.join(path);
        // The longest existing directory above the file, resolved; the rest applied by hand.
        let mut base = abs.clone();
        let mut rest = Vec::new();
        loop {
            match base.parent() {
                Some(parent) if base != parent => {
                    rest.push(base.file_name().map(|n| n.to_owned()));
                    base = parent.to_path_buf();
                    if let Ok(c) = base.canonicalize() {
                        base = c;
                        break;
                    }
                }
                _ => break,
            }
        }
        let mut out = base;
        for part in rest.into_iter().rev() {
            match part {
                Some(name) => {
                    for c in Path::new(&name).components() {
                        match c {
                            Component::ParentDir => {
                                out.pop();
                            }
                            Component::Normal(n) => out.push(n),
                            _ => {}
                        }
                    }
                }
                // `..` as the last part of a path has no file name.
                None => {
                    out.pop();
                }
            }
        }
        Ok(FileId {
            path: out,
            inode: inode(path),
        })
    }

    /// Whether both name the same file.
    pub fn same(&self, other: &FileId) -> bool {
        self.path == other.path || (self.inode.is_some() && self.inode == other.inode)
    }
}

#[cfg(unix)]
fn inode(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn inode(_: &Path) -> Option<(u64, u64)> {
    None
}

/// A new temporary file beside `path`, `.NAME.<pid>.<n>.partial`, created exclusively (so
/// two writers never share one) and registered for [`remove_partials`].
pub(super) fn create_partial(path: &Path) -> std::io::Result<(PathBuf, std::fs::File)> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned());
    loop {
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!(".{name}.{}.{n}.partial", std::process::id()));
        let mut list = PARTIALS.lock().unwrap_or_else(|e| e.into_inner());
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
        {
            Ok(f) => {
                list.push(tmp.clone());
                return Ok((tmp, f));
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
}

/// Forgets `tmp` (renamed into place, or removed).
pub(super) fn release_partial(tmp: &Path) {
    let mut list = PARTIALS.lock().unwrap_or_else(|e| e.into_inner());
    list.retain(|p| p != tmp);
}

/// Removes every temporary file being written (for an abort: the writes never finish).
pub fn remove_partials() {
    let list = PARTIALS.lock().unwrap_or_else(|e| e.into_inner());
    for p in list.iter() {
        let _ = std::fs::remove_file(p);
    }
}
