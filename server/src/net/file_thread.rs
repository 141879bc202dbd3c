//! The holodeck file on its own thread: async tasks send it requests over a
//! channel and await the answers, so disk reads, writes and fsyncs never stall
//! the network executor.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use holodeck_protocol::{BeamKey, RayRecord};
use tokio::sync::{mpsc, oneshot, OwnedSemaphorePermit, Semaphore};

use holodeck_file::storage::{FileSummary, HoloFile, Result, StorageError};

/// Beams read from the file: each key with its rays.
pub type Beams = Vec<(BeamKey, Vec<RayRecord>)>;

enum Request {
    /// The packets, and their share of [`QUEUED_RAYS`], given back once stored.
    Append(Vec<(BeamKey, Vec<RayRecord>)>, OwnedSemaphorePermit),
    Read(Vec<(BeamKey, u64)>, oneshot::Sender<Result<Beams>>),
    Lens(oneshot::Sender<Vec<Vec<u64>>>),
    Clobber(oneshot::Sender<Result<()>>),
    Adopt(String, bool, oneshot::Sender<Result<()>>),
    Len(BeamKey, oneshot::Sender<u64>),
    Flush(oneshot::Sender<Result<u64>>),
    Summary(oneshot::Sender<FileSummary>),
}

/// Requests the storage thread may have waiting.
const QUEUE: usize = 4096;

/// Rays that may wait for the storage thread. Everything else (a commit, a
/// display's read) queues behind them, so this bounds how long those wait
/// when samplers bring more than the disk takes: a fifth of a second of
/// appending or so.
const QUEUED_RAYS: usize = 1 << 20;

/// A handle to the storage thread; cheap to clone.
#[derive(Clone)]
pub struct FileThread {
    tx: mpsc::Sender<Request>,
    /// Permits for [`QUEUED_RAYS`].
    queued: Arc<Semaphore>,
    refusing: Arc<AtomicBool>,
    /// Why the file first refused rays.
    refusal: Arc<Mutex<Option<String>>>,
}

/// The storage thread itself; joining it closes the file after a final flush.
pub struct StoreThread {
    handle: JoinHandle<Result<()>>,
}

impl FileThread {
    /// Moves `file` onto a new thread.
    pub fn spawn(mut file: HoloFile) -> (FileThread, StoreThread) {
        let (tx, mut rx) = mpsc::channel::<Request>(QUEUE);
        let refusing = Arc::new(AtomicBool::new(false));
        let refused = Arc::clone(&refusing);
        let refusal = Arc::new(Mutex::new(None));
        let reason = Arc::clone(&refusal);
        let handle = std::thread::spawn(move || -> Result<()> {
            while let Some(req) = rx.blocking_recv() {
                match req {
                    Request::Append(packets, _permit) => {
                        for (key, rays) in packets {
                            let Err(e) = file.append(key, &rays) else { continue };
                            // Log the first refusal only: every later packet meets the same wall.
                            if !refused.load(Ordering::SeqCst) {
                                // A full DISKSPACE is the limit doing its job (the
                                // service says so as it stops); anything else is an error.
                                match &e {
                                    StorageError::DiskSpace { .. } => tracing::info!("storing rays of {key:?}: {e}"),
                                    _ => tracing::error!("storing rays of {key:?}: {e}"),
                                }
                                let why = match e {
                                    StorageError::DiskSpace { limit, .. } => {
                                        format!("DISKSPACE reached: the limit is {limit} bytes")
                                    }
                                    e => e.to_string(),
                                };
                                if let Ok(mut r) = reason.lock() {
                                    *r = Some(why);
                                }
                                // Raised after the reason is in: whoever sees the
                                // flag can say why (only this thread sets it).
                                refused.store(true, Ordering::SeqCst);
                            }
                        }
                    }
                    Request::Read(wanted, reply) => {
                        let mut out = Vec::with_capacity(wanted.len());
                        let from: std::collections::HashMap<BeamKey, u64> = wanted.iter().copied().collect();
                        let keys: Vec<BeamKey> = wanted.iter().map(|w| w.0).collect();
                        let r = file.read_beams(&keys, |k, rays| {
                            let skip = from.get(&k).copied().unwrap_or(0).min(rays.len() as u64) as usize;
                            if skip < rays.len() {
                                out.push((k, rays[skip..].to_vec()));
                            }
                        });
                        let _ = reply.send(r.map(|_| out));
                    }
                    Request::Clobber(reply) => {
                        let r = file.clobber();
                        if r.is_ok() {
                            refused.store(false, Ordering::SeqCst);
                            if let Ok(mut r) = reason.lock() {
                                *r = None;
                            }
                        }
                        let _ = reply.send(r);
                    }
                    Request::Adopt(scene, keep, reply) => {
                        let r = if keep {
                            let stale = file.summary().rays() > 0;
                            file.flush().and_then(|()| file.set_scene(&scene, stale))
                        } else {
                            file.clobber().and_then(|()| file.set_scene(&scene, false))
                        };
                        if r.is_ok() && !keep {
                            refused.store(false, Ordering::SeqCst);
                            if let Ok(mut r) = reason.lock() {
                                *r = None;
                            }
                        }
                        let _ = reply.send(r);
                    }
                    Request::Lens(reply) => {
                        let lens = file
                            .sections()
                            .iter()
                            .enumerate()
                            .map(|(si, s)| {
                                (0..s.beam_count())
                                    .map(|b| file.beam_len(BeamKey::new(si as u32, b)).unwrap_or(0))
                                    .collect()
                            })
                            .collect();
                        let _ = reply.send(lens);
                    }
                    Request::Len(key, reply) => {
                        let _ = reply.send(file.beam_len(key).unwrap_or(0));
                    }
                    Request::Flush(reply) => {
                        let _ = reply.send(file.flush().map(|()| file.summary().rays()));
                    }
                    Request::Summary(reply) => {
                        let _ = reply.send(file.summary());
                    }
                }
            }
            file.close()
        });
        let queued = Arc::new(Semaphore::new(QUEUED_RAYS));
        (
            FileThread {
                tx,
                queued,
                refusing,
                refusal,
            },
            StoreThread { handle },
        )
    }

    fn gone() -> StorageError {
        StorageError::Io {
            path: "holodeck file".into(),
            op: "reaching the storage thread",
            source: std::io::Error::other("the storage thread has stopped"),
        }
    }

    /// True once the file has refused rays (DISKSPACE reached, or a write
    /// failed): tracing more is wasted.
    pub fn refusing(&self) -> bool {
        self.refusing.load(Ordering::SeqCst)
    }

    /// Why the file refuses rays, once it does: its DISKSPACE limit, or the
    /// error that stopped writing (a full disk, a failed write or sync).
    pub fn refusal(&self) -> Option<String> {
        self.refusal.lock().ok().and_then(|r| r.clone())
    }

    /// Queues rays for a beam.
    /// Waits while the storage thread is [`QUEUED_RAYS`] rays or [`QUEUE`]
    /// requests behind: samplers are then slowed to what the disk takes,
    /// memory stays bounded, and a commit waits for little.
    pub async fn append(&self, key: BeamKey, rays: Vec<RayRecord>) {
        self.append_many(vec![(key, rays)]).await;
    }

    /// Appends the rays of several packets, in order, in one request to the
    /// storage thread (a sampler's packets that arrived together).
    pub async fn append_many(&self, packets: Vec<(BeamKey, Vec<RayRecord>)>) {
        if packets.is_empty() {
            return;
        }
        let rays: usize = packets.iter().map(|(_, r)| r.len()).sum();
        let Ok(permit) = Arc::clone(&self.queued)
            .acquire_many_owned(rays.clamp(1, QUEUED_RAYS) as u32)
            .await
        else {
            return; // never closed
        };
        let _ = self.tx.send(Request::Append(packets, permit)).await;
    }

    /// Reads beams (in file order, through the cache), each from the given
    /// ray on (rays already sent are not read again); beams with nothing past
    /// that point are left out.
    pub async fn read(&self, wanted: Vec<(BeamKey, u64)>) -> Result<Beams> {
        let (tx, rx) = oneshot::channel();
        self.tx
            .send(Request::Read(wanted, tx))
            .await
            .map_err(|_| FileThread::gone())?;
        rx.await.map_err(|_| FileThread::gone())?
    }

    /// Deletes every ray in the file (durably).
    pub async fn clobber(&self) -> Result<()> {
        let (tx, rx) = oneshot::channel();
        self.tx
            .send(Request::Clobber(tx))
            .await
            .map_err(|_| FileThread::gone())?;
        rx.await.map_err(|_| FileThread::gone())?
    }

    /// Makes the file the holodeck of the scene with content hash `scene`,
    /// durably: its rays are deleted first, or with `keep` kept and marked
    /// stale.
    pub async fn adopt(&self, scene: String, keep: bool) -> Result<()> {
        let (tx, rx) = oneshot::channel();
        self.tx
            .send(Request::Adopt(scene, keep, tx))
            .await
            .map_err(|_| FileThread::gone())?;
        rx.await.map_err(|_| FileThread::gone())?
    }

    /// Rays held by every beam, by section.
    pub async fn lens(&self) -> Result<Vec<Vec<u64>>> {
        let (tx, rx) = oneshot::channel();
        self.tx.send(Request::Lens(tx)).await.map_err(|_| FileThread::gone())?;
        rx.await.map_err(|_| FileThread::gone())
    }

    /// Rays a beam holds.
    pub async fn len(&self, key: BeamKey) -> u64 {
        let (tx, rx) = oneshot::channel();
        if self.tx.send(Request::Len(key, tx)).await.is_err() {
            return 0;
        }
        rx.await.unwrap_or(0)
    }

    /// Counts for a progress report.
    pub async fn summary(&self) -> Option<FileSummary> {
        let (tx, rx) = oneshot::channel();
        self.tx.send(Request::Summary(tx)).await.ok()?;
        rx.await.ok()
    }

    /// Makes everything stored so far durable; returns the rays the file
    /// then holds, every one of which survives a crash from here on.
    pub async fn flush(&self) -> Result<u64> {
        let (tx, rx) = oneshot::channel();
        self.tx.send(Request::Flush(tx)).await.map_err(|_| FileThread::gone())?;
        rx.await.map_err(|_| FileThread::gone())?
    }
}

impl StoreThread {
    /// Waits for the thread (after every [`FileThread`] handle is dropped) and reports how closing went.
    pub fn join(self) -> Result<()> {
        self.handle.join().unwrap_or_else(|_| Err(FileThread::gone()))
    }
}
