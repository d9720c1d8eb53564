//! A CPU wake-up latency request (the kernel's PM QoS, `/dev/cpu_dma_latency`): while it
//! is held, idle CPUs use no idle state that takes longer than the request to leave.
//!
//! A thread woken on an idle CPU first waits for that CPU to come out of its idle state. In
//! a deep C-state on bare metal, or halted in a virtual machine (the wake-up then goes
//! through the hypervisor), that exit takes from tens to hundreds of microseconds, and it
//! is the tail of every wake-up outside the cycle (the control thread answering a request,
//! a client waiting for its answer). A request of 0 keeps idle CPUs polling (cpuidle's
//! poll state, or C0), so that a wake-up is a flag the idle loop sees at once. The cost is
//! an idle CPU that does not sleep: more power and heat, which real-time control PCs
//! accept (it is what `cyclictest` requests by default).
//!
//! The request is the kernel's for as long as the file stays open; [`CpuLatencyRequest`]
//! keeps it open and closing it (drop, or the process ending) withdraws the request.

use std::fs::{File, OpenOptions};
use std::io::{self, Write};
use std::path::Path;

/// The kernel's file for CPU wake-up latency requests.
pub const CPU_LATENCY_FILE: &str = "/dev/cpu_dma_latency";

/// A held CPU wake-up latency request; dropping it withdraws the request.
#[derive(Debug)]
pub struct CpuLatencyRequest {
    _file: File,
    latency_us: u32,
}

impl CpuLatencyRequest {
    /// Asks the kernel that idle CPUs be able to wake within `latency_us` microseconds
    /// (0: do not enter any idle state beyond polling), through [`CPU_LATENCY_FILE`].
    /// Writing the file needs root or write access to it (it is `root:root 0600` on most
    /// systems): `Err` with the system's reason otherwise.
    pub fn new(latency_us: u32) -> io::Result<Self> {
        Self::at(Path::new(CPU_LATENCY_FILE), latency_us)
    }

    /// As [`CpuLatencyRequest::new`], through `path` (tests use a plain file).
    pub fn at(path: &Path, latency_us: u32) -> io::Result<Self> {
        let mut file = OpenOptions::new().write(true).open(path)?;
        // The kernel takes the value as a native-endian 32-bit integer (or as hexadecimal
        // text); a signed value is what it reads, and every u32 we accept fits below 2^31.
        let value = i32::try_from(latency_us).map_err(|_| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("a CPU latency of {latency_us} µs is beyond the kernel's range"),
            )
        })?;
        file.write_all(&value.to_ne_bytes())?;
        Ok(Self {
            _file: file,
            latency_us,
        })
    }

    /// The requested latency, µs.
    pub fn latency_us(&self) -> u32 {
        self.latency_us
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_request_is_the_latency_as_a_native_32_bit_integer() {
        let dir = std::env::temp_dir().join(format!("kerf-rt-latency-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("cpu_dma_latency");
        for latency_us in [0u32, 1, 75, 1_000_000] {
            std::fs::write(&path, b"").unwrap();
            let request = CpuLatencyRequest::at(&path, latency_us).unwrap();
            assert_eq!(request.latency_us(), latency_us);
            let bytes = std::fs::read(&path).unwrap();
            assert_eq!(bytes.len(), 4);
            assert_eq!(
                i32::from_ne_bytes(bytes.try_into().unwrap()),
                latency_us as i32
            );
        }
        assert_eq!(
            CpuLatencyRequest::at(&path, u32::MAX).unwrap_err().kind(),
            io::ErrorKind::InvalidInput
        );
        let missing = dir.join("no-such-file");
        assert_eq!(
            CpuLatencyRequest::at(&missing, 0).unwrap_err().kind(),
            io::ErrorKind::NotFound
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The kernel's file: as root the request is in force while held (reading the file
    /// gives the strictest request of all its holders); otherwise the kernel refuses it.
    #[test]
    fn the_kernel_takes_the_request_as_root_and_refuses_it_otherwise() {
        // SAFETY: geteuid has no arguments and cannot fail.
        let root = unsafe { libc::geteuid() } == 0;
        match CpuLatencyRequest::new(0) {
            Ok(request) => {
                assert!(root, "a non-root user wrote {CPU_LATENCY_FILE}");
                let bytes = std::fs::read(CPU_LATENCY_FILE).unwrap();
                let in_force = i32::from_ne_bytes(bytes[..4].try_into().unwrap());
                assert_eq!(in_force, 0, "the request of 0 µs is not in force");
                drop(request);
            }
            Err(e) => assert!(
                !root && e.kind() == io::ErrorKind::PermissionDenied,
                "{CPU_LATENCY_FILE} refused the request as root: {e}"
            ),
        }
    }
}
