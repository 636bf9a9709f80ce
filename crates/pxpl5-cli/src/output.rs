//! Everything the `pxpl5` command writes goes through here: its report ([`out!`], [`outln!`]),
//! its messages on stderr ([`errln!`]) and its files ([`dest`], [`write_all`]).
//!
//! # Printing
//!
//! The tidy test forbids `println!`, `print!`, `eprintln!` and `eprint!` in this crate, which
//! panic when their stream fails.
//!
//! - **A closed stdout is not an error.** When the reader of stdout stops reading (EPIPE, as in
//!   `pxpl5 radiosity | head -1`), the rest of the report is discarded and the command ends as it
//!   would have: exit code 0 when it succeeded. Commands print their report last, after their
//!   files are written, so a closed pipe loses nothing but text no one reads. This is what
//!   ripgrep does, rather than the 141 of a process killed by SIGPIPE: a reader that stops once it
//!   has what it wanted is not a failure.
//! - **Any other failure of stdout is an error naming stdout** (a full device: `> /dev/full`,
//!   a full disk), exit code 2, as for any output the user chose that cannot be written.
//! - **Stderr failures are ignored**: there is nowhere left to report them.
//!
//! - **When a file output is `-`** (stdout), stdout carries that file alone and the report goes
//!   to stderr instead.
//!
//! Each print is flushed at once, so a failure surfaces at the print that caused it and nothing
//! waits in a buffer for the process's exit, where std would drop its error.
//!
//! # Files
//!
//! An output path never loses what it points at. [`dest`] looks at the path before the command
//! does any work, following symlinks to their end:
//!
//! - a regular file, or nothing yet: the file is written to a temporary file beside it (in the
//!   same directory, so on the same file system) and renamed over it, so that it is either the
//!   old file or the whole new one; missing parent directories are created. A symlink to a
//!   regular file stays a symlink: the file it points to is the one replaced (with the
//!   permissions it had).
//! - an existing file that is not regular (a FIFO, a device such as `/dev/null`, a symlink to
//!   one): it is opened and written through, never replaced.
//! - a directory, a read-only file, a path under a regular file, or a directory where no file can
//!   be created: an error naming the path, exit code 2, before any work.
//! - `-`, for the outputs that take it (`--trace`, `--vcd`): stdout.
//!
//! A command computes everything first and then hands all its files to [`write_all`], which
//! writes them all or none (see there); two outputs to one file are refused ([`distinct`]).
//! A file too large to hold in memory (a streamed `.pftrace`) is a [`Spool`]: written during the
//! run to its temporary file (beside the file it replaces, or in the system's temporary
//! directory for stdout, a FIFO or a device), then handed to [`write_all`] with the others.

use std::fmt;
use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::UserError;

/// Set once a write to stdout found the pipe closed: later writes are discarded.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Set when a file output goes to stdout: the report goes to stderr.
static REPORT_TO_STDERR: AtomicBool = AtomicBool::new(false);

/// Print to stdout, as `print!` does, through [`print()`].
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::output::print(format_args!($($arg)*))
    };
}

/// Print a line to stdout, as `println!` does, through [`print()`].
macro_rules! outln {
    () => {
        $crate::output::print(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::output::print(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// Print a line to stderr, as `eprintln!` does, ignoring a failure of stderr.
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::output::print_stderr(format_args!("{}\n", format_args!($($arg)*)))
    };
}

pub(crate) use {errln, out, outln};

/// Write the report's `args` to stdout and flush. A closed pipe is not an error (see the module
/// doc); any other failure is a [`UserError`] naming stdout. When a file output goes to stdout,
/// the report goes to stderr.
pub fn print(args: fmt::Arguments) -> Result<(), UserError> {
    if REPORT_TO_STDERR.load(Ordering::Relaxed) {
        print_stderr(args);
        return Ok(());
    }
    write_stdout(|w| w.write_fmt(args))
}

/// Write a file's `bytes` to stdout and flush, as [`print()`] does.
fn print_bytes(bytes: &[u8]) -> Result<(), UserError> {
    write_stdout(|w| w.write_all(bytes))
}

/// Write `args` to stderr; a failure is ignored.
pub fn print_stderr(args: fmt::Arguments) {
    let mut err = io::stderr().lock();
    let _ = err.write_fmt(args).and_then(|()| err.flush());
}

fn write_stdout(
    write: impl FnOnce(&mut io::StdoutLock) -> io::Result<()>,
) -> Result<(), UserError> {
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        return Ok(());
    }
    let mut out = io::stdout().lock();
    match write(&mut out).and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == io::ErrorKind::BrokenPipe => {
            STDOUT_CLOSED.store(true, Ordering::Relaxed);
            Ok(())
        }
        Err(e) => Err(UserError(format!("stdout: cannot write: {e}"))),
    }
}

/// Where one output goes, decided by what its path is (see the module doc).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Dest {
    /// `-`: stdout.
    Stdout,
    /// A regular file or nothing yet, at the end of the path's symlinks: written to a temporary
    /// file beside it and renamed over it.
    Replace(PathBuf),
    /// An existing file that is not regular (a FIFO, a device, a symlink to one): opened and
    /// written, never replaced.
    Through(PathBuf),
}

/// Decide where the output `what` (the option, e.g. `--trace`) given as `path` goes, or say, naming
/// both, why it cannot go there. `-` is stdout when `dash_is_stdout`, and then the report goes to
/// stderr ([`print()`]). Nothing is created: a directory's capacity to take a file is probed with a
/// file removed at once.
pub fn dest(what: &str, path: &Path, dash_is_stdout: bool) -> Result<Dest, UserError> {
    if dash_is_stdout && path == Path::new("-") {
        REPORT_TO_STDERR.store(true, Ordering::Relaxed);
        return Ok(Dest::Stdout);
    }
    let bad = |problem: &str| UserError(format!("{what} {}: {problem}", path.display()));
    let names_a_directory = path.as_os_str().to_string_lossy().ends_with('/');
    if names_a_directory || path.file_name().is_none() {
        return Err(bad("names a directory; a file is expected here"));
    }
    let in_a_directory = |end: io::Result<PathBuf>| {
        let end = end.map_err(|e| bad(&format!("cannot follow its symbolic links: {e}")))?;
        match dir_problem(&parent_dir(&end)) {
            Some(problem) => Err(bad(&problem)),
            None => Ok(Dest::Replace(end)),
        }
    };
    // The kernel follows the symlinks, /proc's too (`/dev/stdout`).
    match fs::metadata(path) {
        Ok(m) if m.is_dir() => Err(bad("is a directory; a file is expected here")),
        Ok(m) if m.permissions().readonly() => Err(bad("is read-only")),
        Ok(m) if m.is_file() => in_a_directory(fs::canonicalize(path)),
        Ok(_) => Ok(Dest::Through(path.to_path_buf())),
        // Nothing there (or a symlink to nothing), or under a file: dir_problem says which.
        Err(e) if is_missing(&e) => in_a_directory(follow_symlinks(path)),
        Err(e) => Err(bad(&format!("cannot read what it is: {e}"))),
    }
}

/// Check that `dir` is a directory where files can be created, or can be created as one: its
/// nearest existing ancestor must be a directory that takes a file (a probe, removed at once).
/// Creates nothing.
pub fn check_dir(what: &str, dir: &Path) -> Result<(), UserError> {
    dir_problem(dir).map_or(Ok(()), |problem| {
        Err(UserError(format!("{what} {}: {problem}", dir.display())))
    })
}

/// What keeps `dir` from taking files, if anything ([`check_dir`]).
fn dir_problem(dir: &Path) -> Option<String> {
    for ancestor in dir.ancestors() {
        let ancestor = if ancestor.as_os_str().is_empty() {
            Path::new(".")
        } else {
            ancestor
        };
        match fs::metadata(ancestor) {
            Ok(m) if m.is_dir() => {
                let probe = ancestor.join(format!(".pxpl5-probe-{}", std::process::id()));
                return fs::OpenOptions::new()
                    .write(true)
                    .create_new(true)
                    .open(&probe)
                    .and_then(|_| fs::remove_file(&probe))
                    .err()
                    .map(|e| format!("cannot write in {}: {e}", ancestor.display()));
            }
            Ok(_) => return Some(format!("{} is not a directory", ancestor.display())),
            Err(e) if is_missing(&e) => {}
            Err(e) => return Some(format!("{}: {e}", ancestor.display())),
        }
    }
    Some("no part of it exists".to_string())
}

/// Whether `e` says that a path does not exist, or goes through a file that is not a directory.
fn is_missing(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::NotFound | io::ErrorKind::NotADirectory
    )
}

/// `path` with its symbolic links followed to the end, for a path that leads to nothing: where a
/// new file would be (a symlink to a missing file creates that file).
fn follow_symlinks(path: &Path) -> io::Result<PathBuf> {
    let mut p = path.to_path_buf();
    // Linux's limit on the links of one path.
    for _ in 0..40 {
        match fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                // A relative target is relative to the link's directory.
                p = parent_dir(&p).join(fs::read_link(&p)?);
            }
            _ => return Ok(p),
        }
    }
    Err(io::Error::other("too many levels of symbolic links"))
}

/// The directory `path` is in (`.` for a bare file name).
fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Fail, naming it, if two of `dests` are the same file or both stdout: the second would
/// overwrite the first.
pub fn distinct<'a>(dests: impl IntoIterator<Item = &'a Dest>) -> Result<(), UserError> {
    let mut seen = std::collections::BTreeSet::new();
    for dest in dests {
        let key = match dest {
            Dest::Stdout => None,
            Dest::Replace(p) | Dest::Through(p) => {
                Some(std::path::absolute(p).unwrap_or_else(|_| p.clone()))
            }
        };
        if !seen.insert(key.clone()) {
            let what = key.map_or("stdout".to_string(), |p| p.display().to_string());
            return Err(UserError(format!(
                "{what}: two outputs would write it; give each its own"
            )));
        }
    }
    Ok(())
}

/// Write each of `files` to its destination, all or nothing as far as files can be: first every
/// replaced file to a temporary file beside it (creating missing directories), then the files
/// written through and stdout, and only then the renames. A failure before the renames removes
/// the temporary files and the directories created, so that the paths are as they were (a FIFO,
/// a device or stdout may have received part of its bytes); only a failing rename, after the
/// others, can leave some files replaced. An error names the file.
pub fn write_all(files: &[(Dest, Vec<u8>)], spools: Vec<Spool>) -> Result<(), UserError> {
    distinct(
        files
            .iter()
            .map(|(dest, _)| dest)
            .chain(spools.iter().map(|s| &s.dest)),
    )?;
    let mut created = Vec::new();
    let mut temps: Vec<(PathBuf, &Path)> = Vec::new();
    let undo = |temps: &[(PathBuf, &Path)], created: &[PathBuf]| {
        for (tmp, _) in temps {
            let _ = fs::remove_file(tmp);
        }
        // Deepest first; a directory something else wrote into in the meantime stays.
        for dir in created.iter().rev() {
            let _ = fs::remove_dir(dir);
        }
    };
    let staged = files.iter().try_for_each(|(dest, bytes)| {
        if let Dest::Replace(path) = dest {
            create_dirs(&parent_dir(path), &mut created).map_err(|e| cannot_write(path, e))?;
            temps.push((write_temp(path, bytes)?, path));
        }
        Ok(())
    });
    // Spooled files replacing a file are staged already (their directories made by the spool).
    for spool in &spools {
        if let Dest::Replace(path) = &spool.dest {
            temps.push((spool.tmp.clone(), path));
        }
    }
    let passed = staged.and_then(|()| {
        files.iter().try_for_each(|(dest, bytes)| match dest {
            Dest::Stdout => print_bytes(bytes),
            Dest::Through(path) => write_through(path, |f| f.write_all(bytes)),
            Dest::Replace(_) => Ok(()),
        })?;
        spools.iter().try_for_each(|spool| {
            let copy = |w: &mut dyn Write| {
                let mut from = fs::File::open(&spool.tmp)?;
                io::copy(&mut from, w).map(|_| ())
            };
            match &spool.dest {
                Dest::Stdout => write_stdout(|w| copy(w)),
                Dest::Through(path) => write_through(path, |f| copy(f)),
                Dest::Replace(_) => Ok(()),
            }
        })
    });
    if let Err(e) = passed {
        undo(&temps, &created);
        return Err(e);
    }
    for (k, (tmp, path)) in temps.iter().enumerate() {
        if let Err(e) = fs::rename(tmp, path) {
            undo(&temps[k..], &[]);
            return Err(cannot_write(path, e));
        }
    }
    // Renamed into place, or copied out of the system's temporary directory (Drop removes that
    // copy); the directories made for them stay.
    spools.into_iter().for_each(Spool::written);
    Ok(())
}

/// A file written while the command runs, too large to hold in memory: see the module doc.
/// Dropped before [`write_all`] wrote it (the run failed), it removes its temporary file and
/// the directories it created, so the destination is as it was.
#[derive(Debug)]
pub struct Spool {
    dest: Dest,
    tmp: PathBuf,
    /// Set once written: the directories created now hold the file.
    keep_dirs: bool,
}

/// The directories the spools of this process created, while no file written holds them. A
/// spool dropped unwritten removes those above its temporary file that are empty then: the
/// last of several spools in one new directory (a radiosity run's traces, one per method) takes
/// it away, whichever spool made it.
static SPOOL_DIRS: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn spool_dirs() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    // A panic elsewhere while the list was held leaves it as it was: a list of paths.
    SPOOL_DIRS.lock().unwrap_or_else(|e| e.into_inner())
}

impl Spool {
    /// Drops the spool of a file written: the directories made for it hold it now.
    fn written(mut self) {
        self.keep_dirs = true;
    }

    /// The directory of the temporary file: where a trace may put files of its own that end
    /// with the run (on the destination's file system, when the destination is a file).
    pub fn dir(&self) -> PathBuf {
        parent_dir(&self.tmp)
    }

    /// The spool of `dest` and its temporary file, open for writing. Fails, naming the path, when
    /// the temporary file cannot be created.
    pub fn create(dest: &Dest) -> Result<(Spool, fs::File), UserError> {
        static NEXT: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        // Held until the file is open: spools made at once (radiosity's methods, each on a
        // thread) would otherwise both find a new directory missing and both create it, and a
        // spool dropped meanwhile could take away the directory before the file is in it.
        let mut dirs = spool_dirs();
        let mut created = Vec::new();
        let (tmp, shown) = match dest {
            Dest::Replace(path) => {
                create_dirs(&parent_dir(path), &mut created).map_err(|e| cannot_write(path, e))?;
                (temp_beside(path), path.clone())
            }
            Dest::Through(path) => (spool_path(&NEXT), path.clone()),
            Dest::Stdout => (spool_path(&NEXT), PathBuf::from("stdout")),
        };
        dirs.extend(created);
        let mut spool = Spool {
            dest: dest.clone(),
            tmp,
            keep_dirs: false,
        };
        let opened = fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&spool.tmp)
            .and_then(|f| {
                // As write_temp: the replaced file keeps its permissions.
                if let Dest::Replace(path) = dest
                    && let Ok(old) = fs::metadata(path)
                {
                    f.set_permissions(old.permissions())?;
                }
                Ok(f)
            });
        // Released before the spool can be dropped, which takes the list again.
        drop(dirs);
        match opened {
            Ok(f) => Ok((spool, f)),
            Err(e) => {
                spool.tmp = PathBuf::new();
                Err(cannot_write(&shown, e))
            }
        }
    }
}

impl Drop for Spool {
    fn drop(&mut self) {
        // After a rename into place the temporary path names nothing: this removes only a copy
        // left behind.
        if !self.tmp.as_os_str().is_empty() {
            let _ = fs::remove_file(&self.tmp);
        }
        if !self.keep_dirs {
            let mut dirs = spool_dirs();
            // Deepest first; one that holds anything (another spool's file) stays, for now.
            let mut mine: Vec<PathBuf> = dirs
                .iter()
                .filter(|d| self.tmp.starts_with(d))
                .cloned()
                .collect();
            mine.sort_by_key(|d| std::cmp::Reverse(d.components().count()));
            for dir in mine {
                if fs::remove_dir(&dir).is_ok() {
                    dirs.retain(|d| d != &dir);
                }
            }
        }
    }
}

/// A spool file in the system's temporary directory, unique in this process.
fn spool_path(next: &std::sync::atomic::AtomicU32) -> PathBuf {
    let n = next.fetch_add(1, Ordering::Relaxed);
    std::env::temp_dir().join(format!("pxpl5-{}-{n}.spool", std::process::id()))
}

/// The temporary file beside `path` that is renamed over it.
fn temp_beside(path: &Path) -> PathBuf {
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    parent_dir(path).join(format!(".{name}.pxpl5-{}.tmp", std::process::id()))
}

/// Create `dir` and its missing ancestors, adding those it created to `created`, outermost first.
fn create_dirs(dir: &Path, created: &mut Vec<PathBuf>) -> io::Result<()> {
    let missing: Vec<&Path> = dir
        .ancestors()
        .take_while(|d| !d.as_os_str().is_empty() && fs::symlink_metadata(d).is_err())
        .collect();
    for d in missing.into_iter().rev() {
        fs::create_dir(d)?;
        created.push(d.to_path_buf());
    }
    Ok(())
}

fn cannot_write(path: &Path, e: io::Error) -> UserError {
    UserError(format!("{}: cannot write: {e}", path.display()))
}

/// Open the existing special file `path` and `write` to it. A reader that closes a pipe (a FIFO,
/// `/dev/stdout`) before the end is no error, as for stdout.
fn write_through(
    path: &Path,
    write: impl FnOnce(&mut fs::File) -> io::Result<()>,
) -> Result<(), UserError> {
    let written = fs::OpenOptions::new()
        .write(true)
        .open(path)
        .and_then(|mut f| write(&mut f).and_then(|()| f.flush()));
    match written {
        Err(e) if e.kind() != io::ErrorKind::BrokenPipe => Err(cannot_write(path, e)),
        _ => Ok(()),
    }
}

/// Write `bytes` to a new temporary file beside `path`, on disk, with the permissions of the
/// file at `path` if there is one. Returns the temporary file's path; on an error, nothing is
/// left of it.
fn write_temp(path: &Path, bytes: &[u8]) -> Result<PathBuf, UserError> {
    let tmp = temp_beside(path);
    let written = fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .and_then(|mut f| {
            f.write_all(bytes)?;
            if let Ok(old) = fs::metadata(path) {
                f.set_permissions(old.permissions())?;
            }
            f.sync_all()
        });
    match written {
        Ok(()) => Ok(tmp),
        Err(e) => {
            let _ = fs::remove_file(&tmp);
            Err(cannot_write(path, e))
        }
    }
}
