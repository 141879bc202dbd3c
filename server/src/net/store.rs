//! The holodeck file on its own thread: async tasks send it requests over a
//! channel and await the answers, so disk reads, writes and fsyncs never stall
//! the network executor.

use std::thread::JoinHandle;

use holodeck_protocol::{BeamKey, RayRecord};
use tokio::sync::{mpsc, oneshot};

use crate::storage::{FileSummary, HoloFile, Result, StorageError};

/// Beams read from the file: each key with its rays.
pub type Beams = Vec<(BeamKey, Vec<RayRecord>)>;

enum Request {
    Append(BeamKey, Vec<RayRecord>),
    Read(Vec<BeamKey>, oneshot::Sender<Result<Beams>>),
    Len(BeamKey, oneshot::Sender<u64>),
    Flush(oneshot::Sender<Result<()>>),
    Summary(oneshot::Sender<FileSummary>),
}

/// A handle to the storage thread; cheap to clone.
#[derive(Clone)]
pub struct Store {
    tx: mpsc::UnboundedSender<Request>,
}

/// The storage thread itself; joining it closes the file after a final flush.
pub struct StoreThread {
    handle: JoinHandle<Result<()>>,
}

impl Store {
    /// Moves `file` onto a new thread.
    pub fn spawn(mut file: HoloFile) -> (Store, StoreThread) {
        let (tx, mut rx) = mpsc::unbounded_channel::<Request>();
        let handle = std::thread::spawn(move || -> Result<()> {
            while let Some(req) = rx.blocking_recv() {
                match req {
                    Request::Append(key, rays) => {
                        if let Err(e) = file.append(key, &rays) {
                            tracing::error!("storing rays of {key:?}: {e}");
                        }
                    }
                    Request::Read(keys, reply) => {
                        let mut out = Vec::with_capacity(keys.len());
                        let r = file.read_beams(&keys, |k, rays| out.push((k, rays.to_vec())));
                        let _ = reply.send(r.map(|_| out));
                    }
                    Request::Len(key, reply) => {
                        let _ = reply.send(file.beam_len(key).unwrap_or(0));
                    }
                    Request::Flush(reply) => {
                        let _ = reply.send(file.flush());
                    }
                    Request::Summary(reply) => {
                        let _ = reply.send(file.summary());
                    }
                }
            }
            file.close()
        });
        (Store { tx }, StoreThread { handle })
    }

    fn gone() -> StorageError {
        StorageError::Io {
            path: "holodeck file".into(),
            op: "reaching the storage thread",
            source: std::io::Error::other("the storage thread has stopped"),
        }
    }

    /// Queues rays for a beam.
    pub fn append(&self, key: BeamKey, rays: Vec<RayRecord>) {
        let _ = self.tx.send(Request::Append(key, rays));
    }

    /// Reads beams (in file order, through the cache).
    pub async fn read(&self, keys: Vec<BeamKey>) -> Result<Beams> {
        let (tx, rx) = oneshot::channel();
        self.tx.send(Request::Read(keys, tx)).map_err(|_| Store::gone())?;
        rx.await.map_err(|_| Store::gone())?
    }

    /// Rays a beam holds.
    pub async fn len(&self, key: BeamKey) -> u64 {
        let (tx, rx) = oneshot::channel();
        if self.tx.send(Request::Len(key, tx)).is_err() {
            return 0;
        }
        rx.await.unwrap_or(0)
    }

    /// Counts for a progress report.
    pub async fn summary(&self) -> Option<FileSummary> {
        let (tx, rx) = oneshot::channel();
        self.tx.send(Request::Summary(tx)).ok()?;
        rx.await.ok()
    }

    /// Makes everything stored so far durable.
    pub async fn flush(&self) -> Result<()> {
        let (tx, rx) = oneshot::channel();
        self.tx.send(Request::Flush(tx)).map_err(|_| Store::gone())?;
        rx.await.map_err(|_| Store::gone())?
    }
}

impl StoreThread {
    /// Waits for the thread (after every [`Store`] handle is dropped) and reports how closing went.
    pub fn join(self) -> Result<()> {
        self.handle.join().unwrap_or_else(|_| Err(Store::gone()))
    }
}
