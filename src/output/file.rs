//! Output files: checked before any work starts, and written through a temporary name in the
//! same folder that is renamed into place once the file is complete. A crash, a kill or a full
//! disk therefore never leaves a truncated file under the name that was asked for (the rename is
//! atomic on the same file system), and a typo in an output path fails in milliseconds instead
//! of after a long render.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Why an output path cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    #[error("{path}: the folder {folder} does not exist")]
    NoFolder { path: PathBuf, folder: PathBuf },
    #[error("{path}: {folder} is not a folder")]
    NotAFolder { path: PathBuf, folder: PathBuf },
    #[error("{path}: is a folder, not a file")]
    IsFolder { path: PathBuf },
    #[error("{path}: cannot write into {folder}: {source}")]
    NotWritable {
        path: PathBuf,
        folder: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// The folder a file path lives in (`.` for a bare file name).
#[must_use]
pub fn folder_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    }
}

/// A fresh name beside `path` for writing it: hidden, unique to this process and call, and
/// keeping `path`'s extension (writers such as plotters pick the format from it).
#[must_use]
pub fn temp_sibling(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let stem = path
        .file_stem()
        .map_or_else(|| "out".into(), |s| s.to_string_lossy().into_owned());
    let ext = path
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    folder_of(path).join(format!(
        ".{stem}.raygun-tmp-{}-{n}{ext}",
        std::process::id()
    ))
}

/// Checks that `path` can be written: its folder exists and takes a new file, and `path` is not
/// a folder. Writes and removes a probe file; touches nothing else.
pub fn check_writable(path: &Path) -> Result<(), FileError> {
    if path.is_dir() {
        return Err(FileError::IsFolder {
            path: path.to_owned(),
        });
    }
    let folder = folder_of(path);
    if !folder.exists() {
        return Err(FileError::NoFolder {
            path: path.to_owned(),
            folder,
        });
    }
    if !folder.is_dir() {
        return Err(FileError::NotAFolder {
            path: path.to_owned(),
            folder,
        });
    }
    probe(path, &folder)
}

/// Creates `dir` if missing and checks that it takes new files: for commands that write several
/// files into a folder. One rule for every output, file or folder: raygun creates what it is
/// told to write, never the folders above it — the folder `dir` goes in must exist, as a file's
/// must ([`check_writable`]), so a typo in a path fails at once instead of making folders.
pub fn check_folder(dir: &Path) -> Result<(), FileError> {
    if dir.exists() {
        if !dir.is_dir() {
            return Err(FileError::NotAFolder {
                path: dir.to_owned(),
                folder: dir.to_owned(),
            });
        }
    } else {
        let parent = folder_of(dir);
        if !parent.is_dir() {
            return Err(if parent.exists() {
                FileError::NotAFolder {
                    path: dir.to_owned(),
                    folder: parent,
                }
            } else {
                FileError::NoFolder {
                    path: dir.to_owned(),
                    folder: parent,
                }
            });
        }
        create_folder(dir).map_err(|source| FileError::NotWritable {
            path: dir.to_owned(),
            folder: parent,
            source,
        })?;
    }
    probe(&dir.join("probe"), dir)
}

/// Creates the folder `dir` (not the folders above it); one that exists already — another
/// process, an MPI rank, may have made it meanwhile — is what was wanted.
pub fn create_folder(dir: &Path) -> std::io::Result<()> {
    match std::fs::create_dir(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && dir.is_dir() => Ok(()),
        other => other,
    }
}

fn probe(path: &Path, folder: &Path) -> Result<(), FileError> {
    let tmp = temp_sibling(path);
    let not_writable = |source| FileError::NotWritable {
        path: path.to_owned(),
        folder: folder.to_owned(),
        source,
    };
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .map_err(not_writable)?;
    std::fs::remove_file(&tmp).map_err(not_writable)
}

/// Writes `path` by calling `write` with a temporary sibling path, then renames the finished
/// file into place. If `write` fails (or the rename does), the temporary file is removed and
/// `path` is left as it was.
pub fn replace_with<E: From<FileError>>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<(), E> {
    let tmp = temp_sibling(path);
    let result = write(&tmp).and_then(|()| {
        // On disk before it gets the real name, so a power cut cannot leave an empty file
        // under it either.
        if let Ok(f) = std::fs::File::open(&tmp) {
            let _ = f.sync_all();
        }
        std::fs::rename(&tmp, path).map_err(|source| {
            E::from(FileError::Io {
                path: path.to_owned(),
                source,
            })
        })
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// [`replace_with`] for bytes in memory.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    replace_with(path, |tmp| {
        let io = |source| FileError::Io {
            path: path.to_owned(),
            source,
        };
        let mut f = std::fs::File::create(tmp).map_err(io)?;
        f.write_all(bytes).map_err(io)?;
        f.flush().map_err(io)
    })
}

/// The files one run writes, taken back if the run fails before it ends: a full disk halfway
/// through a command that writes several files leaves none of them (each file is already whole
/// or absent, [`replace_with`]; this makes the set whole or absent). Folders the run created are
/// removed as well when they are left empty. Call [`OutputSet::finish`] once everything is
/// written; dropped without it (an error, a panic), the set is removed.
#[derive(Debug, Default)]
pub struct OutputSet {
    files: Vec<PathBuf>,
    folders: Vec<PathBuf>,
    finished: bool,
}

impl OutputSet {
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// [`check_folder`], remembering the folder if it creates it.
    pub fn folder(&mut self, dir: &Path) -> Result<(), FileError> {
        let created = !dir.exists();
        check_folder(dir)?;
        if created {
            self.folders.push(dir.to_owned());
        }
        Ok(())
    }

    /// Counts `path` as written by this run.
    pub fn add(&mut self, path: &Path) {
        self.files.push(path.to_owned());
    }

    /// [`write_bytes`], counted in the set.
    pub fn write_bytes(&mut self, path: &Path, bytes: &[u8]) -> Result<(), FileError> {
        write_bytes(path, bytes)?;
        self.add(path);
        Ok(())
    }

    /// Keeps everything written: the run succeeded.
    pub fn finish(mut self) {
        self.finished = true;
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        if self.finished {
            return;
        }
        for f in self.files.iter().rev() {
            let _ = std::fs::remove_file(f);
        }
        for d in self.folders.iter().rev() {
            // Only an empty folder: anything else in it is not this run's.
            let _ = std::fs::remove_dir(d);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh folder for one test, which removes it when it passes.
    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("raygun-file-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn names(d: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temporary() {
        let d = dir("fail");
        let path = d.join("r.png");
        std::fs::write(&path, b"old").unwrap();
        let r: Result<(), FileError> = replace_with(&path, |tmp| {
            std::fs::write(tmp, b"half").unwrap();
            Err(FileError::Io {
                path: tmp.to_owned(),
                source: std::io::Error::other("disk full"),
            })
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(names(&d), ["r.png"]);
        write_bytes(&path, b"new").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        assert_eq!(names(&d), ["r.png"]);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn the_temporary_keeps_the_extension_and_hides() {
        let t = temp_sibling(Path::new("out/plot.png"));
        let name = t.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            name.starts_with(".plot.") && name.ends_with(".png"),
            "{name}"
        );
        assert_eq!(t.parent().unwrap(), Path::new("out"));
        assert_ne!(
            temp_sibling(Path::new("a.exr")),
            temp_sibling(Path::new("a.exr"))
        );
    }

    #[test]
    fn checks_name_the_missing_folder_and_reject_folders() {
        let d = dir("check");
        check_writable(&d.join("ok.exr")).unwrap();
        let e = check_writable(&d.join("nope/r.png")).unwrap_err();
        assert!(matches!(e, FileError::NoFolder { .. }), "{e}");
        assert!(e.to_string().contains("nope"), "{e}");
        assert!(matches!(
            check_writable(&d).unwrap_err(),
            FileError::IsFolder { .. }
        ));
        std::fs::write(d.join("file"), b"").unwrap();
        assert!(matches!(
            check_writable(&d.join("file/x.png")).unwrap_err(),
            FileError::NotAFolder { .. }
        ));
        assert!(matches!(
            check_folder(&d.join("file")).unwrap_err(),
            FileError::NotAFolder { .. }
        ));
        // The folder named is made; the folders above it are not (as for a file's folder).
        assert!(matches!(
            check_folder(&d.join("new/deeper")).unwrap_err(),
            FileError::NoFolder { .. }
        ));
        assert!(!d.join("new").exists());
        check_folder(&d.join("new")).unwrap();
        check_folder(&d.join("new/deeper")).unwrap();
        assert!(d.join("new/deeper").is_dir());
        // The probes left nothing behind.
        assert_eq!(names(&d), ["file", "new"]);
        assert!(names(&d.join("new/deeper")).is_empty());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn an_unfinished_output_set_takes_back_its_files_and_new_folders() {
        let d = dir("set");
        std::fs::write(d.join("other.txt"), b"not ours").unwrap();
        let out = d.join("run/inputs");
        let mut set = OutputSet::new();
        set.folder(&d.join("run")).unwrap();
        set.folder(&out).unwrap();
        set.write_bytes(&out.join("a.json"), b"{}").unwrap();
        set.write_bytes(&d.join("b.txt"), b"b").unwrap();
        drop(set);
        assert_eq!(names(&d), ["other.txt"]);
        // Finished, it keeps everything.
        let mut set = OutputSet::new();
        set.folder(&d.join("run")).unwrap();
        set.folder(&out).unwrap();
        set.write_bytes(&out.join("a.json"), b"{}").unwrap();
        set.finish();
        assert_eq!(names(&out), ["a.json"]);
        // A folder that held something before the run is left, with what it held.
        let mut set = OutputSet::new();
        set.folder(&d).unwrap();
        set.write_bytes(&d.join("c.txt"), b"c").unwrap();
        drop(set);
        assert_eq!(names(&d), ["other.txt", "run"]);
        std::fs::remove_dir_all(&d).unwrap();
    }
}
