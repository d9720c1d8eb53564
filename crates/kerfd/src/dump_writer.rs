//! The black box written to a file: the control thread drains the dump rings the cycle
//! fills after a fault or a `kerf dump` request.

use super::*;

/// Writes the black-box dumps that come out of the cycle into the dump directory.
pub(crate) struct DumpWriter {
    machine: String,
    dir: std::path::PathBuf,
    /// The file written for the last fault.
    fault: Option<std::path::PathBuf>,
    written: u64,
}

impl DumpWriter {
    pub(crate) fn new(config: &Config) -> Self {
        DumpWriter {
            machine: config.machine.clone(),
            dir: config.dump_dir(),
            fault: None,
            written: 0,
        }
    }

    pub(crate) fn fault_path(&self) -> Option<&std::path::Path> {
        self.fault.as_deref()
    }

    /// Writes every dump waiting in the ring, gives the rings back; the outcome of dump
    /// `tag` if it was among them.
    pub(crate) fn take(
        &mut self,
        rings: &mut worker::DumpWriterRings,
        tag: Option<u64>,
    ) -> Option<Result<std::path::PathBuf, String>> {
        let mut outcome = None;
        while let Ok(dump) = rings.dumps.pop() {
            let kind = match dump.reason {
                kerf_drive::stage::DumpReason::Fault(_) => "fault",
                kerf_drive::stage::DumpReason::Request(_) => "dump",
            };
            let written = self.write(kind, &dump.recorder);
            match (&written, dump.reason) {
                (Ok(path), kerf_drive::stage::DumpReason::Fault(f)) => {
                    tracing::error!("safety fault: {f}; black box written to {}", path.display());
                    self.fault = Some(path.clone());
                }
                (Err(e), kerf_drive::stage::DumpReason::Fault(f)) => {
                    tracing::error!("safety fault: {f}; the black box could not be written: {e}");
                }
                (Ok(path), _) => tracing::info!("black box written to {}", path.display()),
                (Err(e), _) => tracing::warn!("{e}"),
            }
            if let kerf_drive::stage::DumpReason::Request(t) = dump.reason
                && Some(t) == tag
            {
                outcome = Some(written);
            }
            // The ring goes back to the cycle (the ring to it has room for both).
            let _ = rings.spares.push(dump.recorder);
        }
        outcome
    }

    /// Writes `recorder` as CSV to a new file, through a temporary file renamed at the end.
    pub(crate) fn write(
        &mut self,
        kind: &str,
        recorder: &kerf_drive::recorder::Recorder,
    ) -> Result<std::path::PathBuf, String> {
        self.written += 1;
        let stamp = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        let name = format!(
            "kerf-{}-{kind}-{stamp}-{}-{}.csv",
            self.machine,
            std::process::id(),
            self.written
        );
        let path = self.dir.join(&name);
        let tmp = self.dir.join(format!(".{name}.tmp"));
        let fail =
            |e: std::io::Error| format!("cannot write the black box to {}: {e}", path.display());
        std::fs::create_dir_all(&self.dir).map_err(fail)?;
        let file = std::fs::File::create(&tmp).map_err(fail)?;
        let result = recorder
            .dump(std::io::BufWriter::new(file))
            .and_then(|()| std::fs::rename(&tmp, &path));
        if let Err(e) = result {
            let _ = std::fs::remove_file(&tmp);
            return Err(fail(e));
        }
        Ok(std::fs::canonicalize(&path).unwrap_or(path))
    }
}
