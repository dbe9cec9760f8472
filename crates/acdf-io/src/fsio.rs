//! Files as acdf writes and reads them.
//!
//! **Writing.** Every file acdf writes (MERL tables, sampler files, images,
//! CSV and JSON, plots) goes through [`write_atomic`]: the content streams
//! into a temporary file in the target's folder, is flushed to disk, and
//! the temporary file is then renamed over the target. A reader, a crash,
//! a kill or a full disk therefore sees either the old file or the new one,
//! never a mix or a cut, and two writers of the same target leave one whole
//! file. A target that exists and is not a regular file (a device, a FIFO,
//! a symbolic link, a folder) is refused before anything is written, and
//! an existing file keeps its permissions (and, where the process may, its
//! owner). The temporary file is removed when the write fails and, once
//! [`install_interrupt_cleanup`] has run, when the process is ended by a
//! signal it can catch (SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGABRT, SIGALRM,
//! SIGUSR1, ...: [`CLEANUP_SIGNALS`]; a write past the file-size limit
//! fails with an error instead of SIGXFSZ); only SIGKILL can leave one
//! behind, named
//! `.NAME.PID.N` + [`TEMP_SUFFIX`] beside the target.
//!
//! **Reading.** [`Input`] opens a file and knows its size when it is a
//! regular one, so that a reader checks a header before the body and
//! compares the size the header implies with the real one *before*
//! allocating; a stream without a size (a pipe, `/dev/zero`) is read with a
//! bound and refused past it. [`read_bounded`] is the whole-file form.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard, OnceLock};

use crate::limits;

/// The suffix of the temporary files [`write_atomic`] creates.
pub const TEMP_SUFFIX: &str = ".acdf-tmp";

/// Everything that can go wrong while writing or reading a file; every
/// message names the file.
#[derive(Debug, thiserror::Error)]
pub enum FsError {
    /// The target exists and is not a regular file: replacing it would
    /// destroy a device, a FIFO, a link or a folder.
    #[error(
        "cannot write {}: it is {kind}, not a regular file (acdf replaces only regular files)",
        path.display()
    )]
    NotRegularTarget { path: PathBuf, kind: &'static str },

    /// Creating, writing, flushing or renaming failed (a missing folder, a
    /// full disk, no permission, ...); nothing was left under the target's
    /// name.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: io::Error,
    },

    /// The file could not be opened or read.
    #[error("cannot read {}: {source}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: io::Error,
    },

    /// The path names something that is not a file to read (a folder; for
    /// [`Input::open_regular`], anything but a regular file).
    #[error("cannot read {}: it is {kind}, not a regular file", path.display())]
    NotReadable { path: PathBuf, kind: &'static str },

    /// An output folder's path is taken by something that is not a folder
    /// (a file, a FIFO, a device, a link to nothing).
    #[error("cannot use {} as a folder: it is {kind}", path.display())]
    NotAFolder { path: PathBuf, kind: &'static str },

    /// The file is larger than the reader accepts (the size its format
    /// allows, or the memory limit).
    #[error("{}: {}, more than {limit_what} ({})", path.display(), size_text(*size, *limit), limits::format_bytes(*limit))]
    TooLarge {
        path: PathBuf,
        /// The size when known (a regular file); `None` for a stream that
        /// went on past the limit.
        size: Option<u64>,
        limit: u64,
        limit_what: String,
    },
}

fn size_text(size: Option<u64>, limit: u64) -> String {
    match size {
        Some(s) => format!("{s} bytes"),
        None => format!("a stream of more than {limit} bytes"),
    }
}

/// What a file type is, in words, for errors.
fn kind_of(t: &fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_symlink() {
        "a symbolic link"
    } else if t.is_dir() {
        "a folder"
    } else if t.is_file() {
        "a regular file"
    } else {
        "a special file"
    }
}

/// The temporary files in flight, removed by the interrupt handler.
fn registry() -> MutexGuard<'static, Vec<PathBuf>> {
    static TEMPS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
    TEMPS
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A temporary file beside the target, registered for removal on interrupt
/// and removed on drop unless it was renamed into place.
struct Temp {
    path: Option<PathBuf>,
}

impl Temp {
    fn create(dir: &Path, name: &std::ffi::OsStr, mode: Option<u32>) -> io::Result<(Temp, File)> {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let pid = std::process::id();
        loop {
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let mut file_name = std::ffi::OsString::from(".");
            file_name.push(name);
            file_name.push(format!(".{pid}.{n}{TEMP_SUFFIX}"));
            let path = dir.join(file_name);
            let mut options = OpenOptions::new();
            options.write(true).create_new(true);
            #[cfg(unix)]
            {
                use std::os::unix::fs::OpenOptionsExt;
                // As `std::fs::write` creates files: 0666 less the umask.
                options.mode(mode.unwrap_or(0o666));
            }
            #[cfg(not(unix))]
            let _ = mode;
            // Created and registered under the lock, so that the interrupt
            // handler, which takes the lock for good, sees every file.
            let mut temps = registry();
            match options.open(&path) {
                Ok(file) => {
                    temps.push(path.clone());
                    return Ok((Temp { path: Some(path) }, file));
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
                Err(e) => return Err(e),
            }
        }
    }

    fn unregister(path: &Path) {
        let mut temps = registry();
        if let Some(k) = temps.iter().position(|p| p == path) {
            temps.swap_remove(k);
        }
    }

    /// Rename over `target`; on failure the drop removes the file.
    fn persist(mut self, target: &Path) -> io::Result<()> {
        let path = self.path.take().expect("a live temporary file");
        match fs::rename(&path, target) {
            Ok(()) => {
                Temp::unregister(&path);
                Ok(())
            }
            Err(e) => {
                self.path = Some(path);
                Err(e)
            }
        }
    }
}

impl Drop for Temp {
    fn drop(&mut self) {
        if let Some(path) = self.path.take() {
            let _ = fs::remove_file(&path);
            Temp::unregister(&path);
        }
    }
}

/// The folder a path's file lives in (`.` for a bare name).
fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Write the file at `path` atomically with the content `write` produces
/// (see the module documentation): refuse a target that is not a regular
/// file, stream into a temporary file in the same folder, flush it to disk,
/// give it the permissions (and owner) of the file it replaces, rename it
/// over `path`. On any error the temporary file is removed and `path` is
/// untouched. An error returned by `write` is reported as a write error of
/// `path`, its message kept.
pub fn write_atomic<F>(path: &Path, write: F) -> Result<(), FsError>
where
    F: FnOnce(&mut dyn Write) -> io::Result<()>,
{
    let error = |source| FsError::Write {
        path: path.to_path_buf(),
        source,
    };
    let existing = match fs::symlink_metadata(path) {
        Ok(m) if !m.file_type().is_file() => {
            return Err(FsError::NotRegularTarget {
                path: path.to_path_buf(),
                kind: kind_of(&m.file_type()),
            })
        }
        Ok(m) => Some(m),
        Err(e) if e.kind() == io::ErrorKind::NotFound => None,
        Err(e) => return Err(error(e)),
    };
    let name = path.file_name().ok_or_else(|| {
        error(io::Error::new(
            io::ErrorKind::InvalidInput,
            "the path names no file",
        ))
    })?;
    let dir = parent_dir(path);
    #[cfg(unix)]
    let mode = {
        use std::os::unix::fs::PermissionsExt;
        existing.as_ref().map(|m| m.permissions().mode() & 0o7777)
    };
    #[cfg(not(unix))]
    let mode = None;
    let (temp, file) = Temp::create(dir, name, mode).map_err(error)?;
    let written = (|| -> io::Result<()> {
        let mut out = BufWriter::with_capacity(1 << 16, file);
        write(&mut out)?;
        let file = out.into_inner().map_err(io::IntoInnerError::into_error)?;
        if let Some(m) = &existing {
            keep_owner_and_mode(&file, m)?;
        }
        file.sync_all()
    })();
    written.map_err(error)?;
    temp.persist(path).map_err(error)?;
    // Make the rename itself durable; a folder that cannot be opened or
    // synced (some file systems) changes nothing about the file.
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Give the new file the mode of the one it replaces (the umask applied at
/// creation may have narrowed it) and, where allowed, its owner.
fn keep_owner_and_mode(file: &File, old: &fs::Metadata) -> io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let new = file.metadata()?;
        if new.uid() != old.uid() || new.gid() != old.gid() {
            // Only a privileged process may give a file away; otherwise the
            // file is the writer's, as any new file would be.
            let _ = std::os::unix::fs::fchown(file, Some(old.uid()), Some(old.gid()));
        }
    }
    file.set_permissions(old.permissions())
}

/// The signals whose default action ends the process and that a process
/// can catch, other than those of a fault in the process itself (SIGSEGV,
/// SIGBUS, SIGILL, SIGFPE, SIGTRAP, SIGSYS), SIGPIPE (which Rust programs
/// ignore, seeing an error instead) and SIGXFSZ (see
/// [`install_interrupt_cleanup`]): on each, the temporary files are removed
/// before the process dies of it.
#[cfg(unix)]
pub const CLEANUP_SIGNALS: [i32; 11] = {
    use signal_hook::consts::*;
    [
        SIGHUP, SIGINT, SIGQUIT, SIGABRT, SIGALRM, SIGTERM, SIGUSR1, SIGUSR2, SIGXCPU, SIGVTALRM,
        SIGPROF,
    ]
};

/// Remove the temporary files of [`write_atomic`] when the process is
/// ended by any of [`CLEANUP_SIGNALS`] (SIGINT, SIGTERM, SIGHUP, SIGQUIT,
/// ...), then die of that signal as if no handler had been installed (so a
/// shell sees the usual status). SIGXFSZ, which a write past the file-size
/// limit raises, is caught and does nothing: the write then fails with an
/// error ("File too large") that [`write_atomic`] reports after removing
/// its temporary file, instead of the process dying in the middle of it.
/// Only SIGKILL (and a fault in the process itself) can leave a temporary
/// file behind. For programs: a library should leave its host's signals
/// alone. Calling it again does nothing.
pub fn install_interrupt_cleanup() -> io::Result<()> {
    static INSTALLED: OnceLock<io::Result<()>> = OnceLock::new();
    let result = INSTALLED.get_or_init(|| {
        #[cfg(unix)]
        {
            let file_too_large = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
            signal_hook::flag::register(signal_hook::consts::SIGXFSZ, file_too_large)?;
            let mut signals = signal_hook::iterator::Signals::new(CLEANUP_SIGNALS)?;
            std::thread::Builder::new()
                .name("acdf-interrupt".into())
                .spawn(move || {
                    if let Some(signal) = signals.forever().next() {
                        // Held until the process ends: no new temporary
                        // file can appear after these are removed.
                        let temps = registry();
                        for path in temps.iter() {
                            let _ = fs::remove_file(path);
                        }
                        let _ = signal_hook::low_level::emulate_default_handler(signal);
                        std::process::exit(128 + signal);
                    }
                })?;
        }
        Ok(())
    });
    match result {
        Ok(()) => Ok(()),
        Err(e) => Err(io::Error::new(e.kind(), e.to_string())),
    }
}

/// Make sure `dir` is a folder, creating it and its parents where they are
/// missing; a path taken by anything else (a file, a FIFO, a device, a
/// symbolic link to nothing) is an error that says what is there, instead
/// of the system's "File exists".
pub fn ensure_folder(dir: &Path) -> Result<(), FsError> {
    if let Ok(link) = fs::symlink_metadata(dir) {
        return match fs::metadata(dir) {
            Ok(m) if m.is_dir() => Ok(()),
            Ok(m) => Err(FsError::NotAFolder {
                path: dir.to_path_buf(),
                kind: kind_of(&m.file_type()),
            }),
            Err(_) if link.file_type().is_symlink() => Err(FsError::NotAFolder {
                path: dir.to_path_buf(),
                kind: "a symbolic link to nothing",
            }),
            Err(source) => Err(FsError::Write {
                path: dir.to_path_buf(),
                source,
            }),
        };
    }
    fs::create_dir_all(dir).map_err(|source| {
        // A parent may be what is in the way.
        let blocked = dir
            .ancestors()
            .skip(1)
            .find(|a| fs::symlink_metadata(a).is_ok());
        match blocked.and_then(|a| fs::metadata(a).ok().map(|m| (a, m))) {
            Some((a, m)) if !m.is_dir() => FsError::NotAFolder {
                path: a.to_path_buf(),
                kind: kind_of(&m.file_type()),
            },
            _ => FsError::Write {
                path: dir.to_path_buf(),
                source,
            },
        }
    })
}

/// End the process as a Unix tool does when its output pipe is closed:
/// killed by SIGPIPE (Rust programs ignore the signal and see an error
/// instead; this restores the default action and raises it).
pub fn die_of_broken_pipe() -> ! {
    #[cfg(unix)]
    {
        let _ = signal_hook::low_level::emulate_default_handler(signal_hook::consts::SIGPIPE);
        std::process::exit(128 + signal_hook::consts::SIGPIPE)
    }
    #[cfg(not(unix))]
    std::process::exit(1)
}

/// A file opened for reading, with its size when it is a regular file, so
/// that readers check headers and sizes before they allocate.
#[derive(Debug)]
pub struct Input {
    path: PathBuf,
    file: File,
    len: Option<u64>,
    read: u64,
}

impl Input {
    /// Open `path` (following links). A folder is an error; a device or a
    /// pipe opens, with no known size.
    pub fn open(path: &Path) -> Result<Input, FsError> {
        Input::open_unless(path, |meta| meta.is_dir().then_some("a folder"))
    }

    /// Open `path` only if it is a regular file (after symbolic links):
    /// a folder, FIFO, device or socket is refused from its metadata,
    /// before it is opened, since opening a FIFO waits for a writer. For
    /// files a program keeps for itself (caches) and images, which are
    /// never streams.
    pub fn open_regular(path: &Path) -> Result<Input, FsError> {
        Input::open_unless(path, |meta| {
            (!meta.is_file()).then(|| kind_of(&meta.file_type()))
        })
    }

    /// Open `path` unless `refuse` names, from its metadata, what it is
    /// and why that is not read.
    fn open_unless(
        path: &Path,
        refuse: impl FnOnce(&fs::Metadata) -> Option<&'static str>,
    ) -> Result<Input, FsError> {
        let read_error = |source| FsError::Read {
            path: path.to_path_buf(),
            source,
        };
        let meta = fs::metadata(path).map_err(read_error)?;
        if let Some(kind) = refuse(&meta) {
            return Err(FsError::NotReadable {
                path: path.to_path_buf(),
                kind,
            });
        }
        let file = File::open(path).map_err(read_error)?;
        Ok(Input {
            path: path.to_path_buf(),
            file,
            len: meta.is_file().then_some(meta.len()),
            read: 0,
        })
    }

    /// The path it was opened with.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The size of a regular file; `None` for a device or a pipe.
    pub fn len(&self) -> Option<u64> {
        self.len
    }

    /// Whether it is a regular file of no bytes.
    pub fn is_empty(&self) -> bool {
        self.len == Some(0)
    }

    /// Bytes read so far.
    pub fn position(&self) -> u64 {
        self.read
    }

    /// Up to `n` bytes, fewer only at the end of the file.
    pub fn read_up_to(&mut self, n: usize) -> Result<Vec<u8>, FsError> {
        let mut out = Vec::with_capacity(n.min(1 << 16));
        (&mut self.file)
            .take(n as u64)
            .read_to_end(&mut out)
            .map_err(|source| FsError::Read {
                path: self.path.clone(),
                source,
            })?;
        self.read += out.len() as u64;
        Ok(out)
    }

    /// Everything that is left, at most `max` bytes: a regular file larger
    /// than that is refused from its size before anything is read, a
    /// stream once it goes past `max`. `max_what` names the bound in the
    /// error (`the memory limit`, `the size of a MERL file`, ...).
    pub fn read_rest(&mut self, max: u64, max_what: &str) -> Result<Vec<u8>, FsError> {
        let too_large = |size| FsError::TooLarge {
            path: self.path.clone(),
            size,
            limit: max,
            limit_what: max_what.to_string(),
        };
        if let Some(len) = self.len {
            if len.saturating_sub(self.read) > max {
                return Err(too_large(Some(len)));
            }
        }
        let capacity = self.len.map_or(0, |l| l.saturating_sub(self.read)).min(max);
        let mut out = Vec::with_capacity(capacity as usize);
        (&mut self.file)
            .take(max.saturating_add(1))
            .read_to_end(&mut out)
            .map_err(|source| FsError::Read {
                path: self.path.clone(),
                source,
            })?;
        if out.len() as u64 > max {
            return Err(too_large(None));
        }
        self.read += out.len() as u64;
        Ok(out)
    }
}

/// The whole file at `path`, refused when it is larger than `max` bytes or
/// than the memory limit ([`limits::memory_limit`]), whichever is smaller;
/// `what` names the smaller bound in the error.
pub fn read_bounded(path: &Path, max: u64, max_what: &str) -> Result<Vec<u8>, FsError> {
    let limit = limits::memory_limit();
    let (max, what) = if limit < max {
        (limit, "the memory limit (acdf --memory-limit raises it)")
    } else {
        (max, max_what)
    };
    Input::open(path)?.read_rest(max, what)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn strays(dir: &Path) -> Vec<String> {
        fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(TEMP_SUFFIX))
            .collect()
    }

    #[test]
    fn writes_replace_whole_files() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.txt");
        write_atomic(&path, |w| w.write_all(b"first")).unwrap();
        write_atomic(&path, |w| w.write_all(b"second")).unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"second");
        assert!(strays(dir.path()).is_empty());
    }

    /// A failing writer leaves the old file and no temporary file, and the
    /// error names the target and keeps the writer's message.
    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("keep.bin");
        fs::write(&path, b"old content").unwrap();
        let err = write_atomic(&path, |w| {
            w.write_all(&[7u8; 100_000])?;
            Err(io::Error::other("the encoder gave up"))
        })
        .unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("keep.bin") && text.contains("the encoder gave up"),
            "{text}"
        );
        assert_eq!(fs::read(&path).unwrap(), b"old content");
        assert!(strays(dir.path()).is_empty(), "{:?}", strays(dir.path()));

        let missing = dir.path().join("no/such/folder/x.bin");
        let err = write_atomic(&missing, |w| w.write_all(b"x")).unwrap_err();
        assert!(matches!(err, FsError::Write { .. }), "{err}");
        assert!(err.to_string().starts_with("cannot write"), "{err}");
    }

    #[cfg(unix)]
    #[test]
    fn special_targets_are_refused_and_modes_kept() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("real.txt");
        fs::write(&target, b"real").unwrap();
        let link = dir.path().join("link.txt");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let err = write_atomic(&link, |w| w.write_all(b"x")).unwrap_err();
        assert!(err.to_string().contains("a symbolic link"), "{err}");
        assert!(fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(fs::read(&target).unwrap(), b"real");
        let err = write_atomic(dir.path(), |w| w.write_all(b"x")).unwrap_err();
        assert!(err.to_string().contains("a folder"), "{err}");
        let err = write_atomic(Path::new("/dev/null"), |w| w.write_all(b"x")).unwrap_err();
        assert!(err.to_string().contains("a character device"), "{err}");

        fs::set_permissions(&target, fs::Permissions::from_mode(0o600)).unwrap();
        write_atomic(&target, |w| w.write_all(b"new")).unwrap();
        let mode = fs::metadata(&target).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        assert_eq!(fs::read(&target).unwrap(), b"new");
    }

    #[test]
    fn bounded_reads_refuse_large_files_and_endless_streams() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ten.bin");
        fs::write(&path, [1u8; 10]).unwrap();
        assert_eq!(read_bounded(&path, 10, "ten").unwrap().len(), 10);
        let err = read_bounded(&path, 9, "nine bytes").unwrap_err();
        assert!(
            matches!(err, FsError::TooLarge { size: Some(10), .. }),
            "{err}"
        );
        assert!(err.to_string().contains("nine bytes"), "{err}");
        #[cfg(unix)]
        {
            let err = read_bounded(Path::new("/dev/zero"), 1 << 20, "a megabyte").unwrap_err();
            assert!(matches!(err, FsError::TooLarge { size: None, .. }), "{err}");
        }
        let mut input = Input::open(&path).unwrap();
        assert_eq!(input.len(), Some(10));
        assert_eq!(input.read_up_to(4).unwrap().len(), 4);
        assert_eq!(input.read_rest(6, "six").unwrap().len(), 6);
        assert!(matches!(
            Input::open(dir.path()),
            Err(FsError::NotReadable { .. })
        ));
    }
}
