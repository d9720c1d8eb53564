//! Output files that a failed command never destroys.
//!
//! Every file a command writes (the CSV and plot of `kerf sim`, the recording of `kerf run
//! --record`) is written to a temporary file beside its target and
//! renamed over the target only when the command succeeds ([`Output::commit`]). A command
//! that fails drops the output instead: the temporary file is removed and an existing
//! target is left as it was. The name `-` means standard output. `kerf record --out`, a
//! recorder that runs until stopped, writes its file as it goes ([`Output::create_live`]).

use std::ffi::OsStr;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::Failure;

/// `true` when `path` names standard output.
pub fn is_stdout(path: &Path) -> bool {
    path.as_os_str() == OsStr::new("-")
}

/// Where an output goes while it is written.
enum Sink {
    Stdout(BufWriter<io::Stdout>),
    /// The target itself, written as it goes ([`Output::create_live`]).
    Live(BufWriter<File>),
    /// The temporary file beside the target; `None` once committed.
    File {
        out: Option<BufWriter<File>>,
        temporary: PathBuf,
        target: PathBuf,
    },
}

/// An output being written: standard output, or a temporary file renamed over the target
/// by [`Output::commit`] and removed when dropped uncommitted.
pub struct Output {
    sink: Sink,
    /// The name errors use: the target as given, or `<stdout>`.
    pub name: String,
}

impl Output {
    /// Starts the output `path` (`-`: standard output). Nothing at `path` changes until
    /// [`Output::commit`].
    pub fn create(path: &Path) -> Result<Output, Failure> {
        if is_stdout(path) {
            return Ok(Output {
                sink: Sink::Stdout(BufWriter::new(io::stdout())),
                name: "<stdout>".to_string(),
            });
        }
        let name = path.display().to_string();
        let cannot_create =
            |e: io::Error| Failure::Error(format!("{name}: error: cannot create: {e}"));
        // A device, pipe or socket (`--out /dev/null`, a FIFO) is written in place: a
        // temporary file renamed over it would replace the device with a regular file.
        if let Ok(meta) = std::fs::metadata(path)
            && !meta.is_file()
            && !meta.is_dir()
        {
            let file = std::fs::OpenOptions::new()
                .write(true)
                .open(path)
                .map_err(cannot_create)?;
            return Ok(Output {
                sink: Sink::Live(BufWriter::new(file)),
                name,
            });
        }
        let file_name = path
            .file_name()
            .ok_or_else(|| cannot_create(io::Error::other("not a file name")))?;
        let dir = path.parent().unwrap_or(Path::new(""));
        // Hidden, and unique to this process and output, so that two runs never share one.
        let mut temporary_name = std::ffi::OsString::from(".");
        temporary_name.push(file_name);
        temporary_name.push(format!(".kerf-{}.tmp", std::process::id()));
        let temporary = dir.join(temporary_name);
        // A directory that does not exist, or that cannot be written, fails here, before
        // the command does its work.
        let file = File::create(&temporary).map_err(cannot_create)?;
        Ok(Output {
            sink: Sink::File {
                out: Some(BufWriter::new(file)),
                temporary,
                target: path.to_path_buf(),
            },
            name,
        })
    }

    /// Starts the output `path` (`-`: standard output) by creating it at once and writing
    /// it as rows come: for `kerf record`, which runs until it is stopped and whose file is
    /// watched while it grows. It opens the file only once the daemon has answered, so a
    /// record that cannot start leaves an existing file alone.
    pub fn create_live(path: &Path) -> Result<Output, Failure> {
        if is_stdout(path) {
            return Output::create(path);
        }
        let name = path.display().to_string();
        let file = File::create(path)
            .map_err(|e| Failure::Error(format!("{name}: error: cannot create: {e}")))?;
        Ok(Output {
            sink: Sink::Live(BufWriter::new(file)),
            name,
        })
    }

    /// `true` when the output is standard output.
    pub fn is_stdout(&self) -> bool {
        matches!(self.sink, Sink::Stdout(_))
    }

    /// An error of this output as a failure naming it.
    pub fn error(&self, e: io::Error) -> Failure {
        if self.is_stdout() {
            return Failure::from(e);
        }
        Failure::Error(format!("{}: error: {e}", self.name))
    }

    /// Flushes the output and, for a file, renames it over its target.
    pub fn commit(mut self) -> Result<(), Failure> {
        self.flush().map_err(|e| self.error(e))?;
        if let Sink::File {
            out,
            temporary,
            target,
        } = &mut self.sink
            && let Some(file) = out.take()
        {
            let file = file.into_inner().map_err(|e| e.into_error());
            let synced = file.and_then(|f| f.sync_all());
            if let Err(e) = synced.and_then(|()| std::fs::rename(&*temporary, &*target)) {
                let _ = std::fs::remove_file(&*temporary);
                return Err(Failure::Error(format!("{}: error: {e}", self.name)));
            }
        }
        Ok(())
    }
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match &mut self.sink {
            Sink::Stdout(out) => out.write(buf),
            Sink::Live(out) => out.write(buf),
            Sink::File { out: Some(out), .. } => out.write(buf),
            Sink::File { out: None, .. } => Err(io::Error::other("output already committed")),
        }
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        match &mut self.sink {
            Sink::Stdout(out) => out.write_all(buf),
            Sink::Live(out) => out.write_all(buf),
            Sink::File { out: Some(out), .. } => out.write_all(buf),
            Sink::File { out: None, .. } => Err(io::Error::other("output already committed")),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match &mut self.sink {
            Sink::Stdout(out) => out.flush(),
            Sink::Live(out) => out.flush(),
            Sink::File { out: Some(out), .. } => out.flush(),
            Sink::File { out: None, .. } => Ok(()),
        }
    }
}

impl Drop for Output {
    fn drop(&mut self) {
        if let Sink::File {
            out: Some(_),
            temporary,
            ..
        } = &self.sink
        {
            let _ = std::fs::remove_file(temporary);
        }
    }
}
