//! The tokio runtimes commands run their async work on.

use crate::failure::Failure;

pub fn runtime() -> Result<tokio::runtime::Runtime, Failure> {
    tokio::runtime::Runtime::new().map_err(|e| Failure::Failed(e.into()))
}

/// Runs a role on a runtime of its own, and leaves without waiting for the runtime's blocking
/// threads: Zenoh opens a session on one, which a signal cannot stop (it waits out its connect
/// timeout, a minute in configs/zenoh/).
pub fn role<F: std::future::Future>(work: F) -> Result<F::Output, Failure> {
    let rt = runtime()?;
    let out = rt.block_on(work);
    rt.shutdown_background();
    Ok(out)
}
