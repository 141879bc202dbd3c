//! Serving one display (or admin): beam requests are answered at once with
//! every stored ray the display was not sent yet (read in file order; the
//! paper's "immediate transfer"; all of them when it asks to `resend`),
//! closed by a `Delivered` message; the request then joins the merged request
//! list, and rays traced for it later are streamed as they land. A display
//! keeps what it was sent across views (it reprojects), so a new view costs
//! only the rays it has not seen, and a raised count costs nothing at once.
//!
//! Rays that land while a request is being read are found by epoch and
//! sent on the next wake, so none fall between the read and the request.
//!
//! New rays are not pushed through a queue: samplers only mark the beam dirty
//! in the display's [`DisplayLink`], and this task reads each dirty beam past
//! what it already sent. A display that stops reading holds back only its own
//! task, and its memory stays bounded by the beams it asked for.

use std::collections::HashMap;
use std::sync::Arc;

use holodeck_protocol::wire::{Access, Control, ControlOutcome, ControlReply, Frame, Message, MAX_FRAME};
use holodeck_protocol::{BeamKey, RAY_RECORD_BYTES};

use super::connection::{Connection, ConnectionError};
use super::state::{DisplayLink, Shared};
use holodeck_file::storage::StorageError;

/// Beams read from the store per round trip to the storage thread: bounds the
/// memory one request can pin.
const READ_CHUNK: usize = 2048;

/// Most records in one beam frame (a frame holds at most [`MAX_FRAME`] bytes).
const MAX_FRAME_RAYS: usize = (MAX_FRAME - 64) / RAY_RECORD_BYTES;

/// A display reading beams while samplers may be adding to them: the
/// scheduler notes which beams got rays meanwhile, until the watch ends.
struct Watch<'a> {
    shared: &'a Shared,
    epoch: Option<u64>,
}

impl<'a> Watch<'a> {
    fn new(shared: &'a Shared) -> Watch<'a> {
        Watch {
            epoch: Some(shared.lock_scheduler().watch()),
            shared,
        }
    }

    /// Runs `register` under the scheduler's lock (which names the beams
    /// read) and returns those that got rays since the watch began.
    fn end<'k>(mut self, register: impl FnOnce(&mut crate::schedule::Scheduler) -> &'k [BeamKey]) -> Vec<BeamKey> {
        let epoch = self.epoch.take().unwrap_or(0);
        let mut scheduler = self.shared.lock_scheduler();
        let keys = register(&mut scheduler);
        scheduler.landed_since(keys, epoch)
    }
}

impl Drop for Watch<'_> {
    fn drop(&mut self) {
        if let Some(epoch) = self.epoch {
            self.shared.lock_scheduler().landed_since(&[], epoch);
        }
    }
}

pub(super) async fn serve_display(conn: Connection, shared: &Shared, access: Access) -> Result<(), ConnectionError> {
    let id = shared.id();
    let link = Arc::new(DisplayLink::default());
    shared.lock_displays().insert(id, Arc::clone(&link));
    let result = display_loop(conn, shared, access, id, &link).await;
    shared.lock_displays().remove(&id);
    shared.lock_scheduler().requests().drop_display(id);
    result
}

/// Sends `beams` (each from the ray given on), chunk by chunk; returns the
/// rays sent per beam and in all.
async fn send_beams(
    conn: &mut Connection,
    shared: &Shared,
    wanted: Vec<(BeamKey, u64)>,
) -> Result<Result<(Vec<(BeamKey, u64)>, u64), StorageError>, ConnectionError> {
    let mut sent = Vec::with_capacity(wanted.len());
    let mut total = 0u64;
    for chunk in wanted.chunks(READ_CHUNK) {
        let beams = match shared.store.read(chunk.to_vec()).await {
            Ok(b) => b,
            Err(e) => return Ok(Err(e)),
        };
        let mut frames = Vec::with_capacity(beams.len());
        for (key, records) in beams {
            sent.push((key, records.len() as u64));
            total += records.len() as u64;
            if records.len() <= MAX_FRAME_RAYS {
                frames.push(Frame::Beam { key, records });
            } else {
                // A beam too big for one frame goes in several.
                for part in records.chunks(MAX_FRAME_RAYS) {
                    frames.push(Frame::Beam {
                        key,
                        records: part.to_vec(),
                    });
                }
            }
        }
        conn.write_all(&frames).await?;
    }
    Ok(Ok((sent, total)))
}

/// Serves one display until it leaves, the server stops, or it quits the
/// server: its beam requests, the rays that land in its beams later, its
/// control commands, and progress reports.
async fn display_loop(
    mut conn: Connection,
    shared: &Shared,
    access: Access,
    id: u64,
    link: &DisplayLink,
) -> Result<(), ConnectionError> {
    let mut stop = shared.shutdown.subscribe();
    let mut progress = shared.progress.subscribe();
    // A report goes out at once: the latest, with the connections as they are now.
    let now = shared.progress_now_counts(*progress.borrow_and_update());
    conn.write(&Frame::Message(Message::Progress(now))).await?;
    // Rays of each requested beam this display has been sent.
    let mut sent: HashMap<BeamKey, u64> = HashMap::new();
    let mut generation = shared.generation.load(std::sync::atomic::Ordering::SeqCst);
    loop {
        // The file was clobbered: every beam starts again from its first ray.
        let now = shared.generation.load(std::sync::atomic::Ordering::SeqCst);
        if now != generation {
            generation = now;
            sent.values_mut().for_each(|n| *n = 0);
        }
        let frame = tokio::select! {
            f = conn.read() => f?,
            _ = link.wake.notified() => {
                send_landed(&mut conn, shared, link, &mut sent).await?;
                continue;
            }
            _ = stop.changed() => return Ok(()),
            Ok(()) = progress.changed() => {
                let p = *progress.borrow_and_update();
                conn.write(&Frame::Message(Message::Progress(p))).await?;
                continue;
            }
        };
        let Some(frame) = frame else { return Ok(()) };
        match frame {
            Frame::Message(Message::BeamRequest {
                beams,
                eye,
                replace,
                resend,
            }) => {
                let beams = match checked_request(shared, beams, eye, replace, resend) {
                    Ok(beams) => beams,
                    Err(message) => {
                        conn.write(&Frame::Message(Message::Error { message })).await?;
                        continue;
                    }
                };
                let request = Request {
                    beams,
                    eye,
                    replace,
                    resend,
                };
                answer_request(&mut conn, shared, id, link, &mut sent, request).await?;
            }
            Frame::Message(Message::Control(c)) => {
                if answer_control(&mut conn, shared, access, c).await? {
                    return Ok(());
                }
            }
            _ => {
                let message = "displays send beam requests and control commands".to_string();
                conn.write(&Frame::Message(Message::Error { message })).await?;
            }
        }
    }
}

/// Sends the rays that landed in the display's beams since it was last
/// sent them (those past `sent`), and counts them in `sent`.
async fn send_landed(
    conn: &mut Connection,
    shared: &Shared,
    link: &DisplayLink,
    sent: &mut HashMap<BeamKey, u64>,
) -> Result<(), ConnectionError> {
    let dirty: Vec<(BeamKey, u64)> = link
        .take()
        .into_iter()
        .filter_map(|k| sent.get(&k).map(|&n| (k, n)))
        .collect();
    if dirty.is_empty() {
        return Ok(());
    }
    match send_beams(conn, shared, dirty).await? {
        Ok((got, _)) => {
            for (k, n) in got {
                *sent.entry(k).or_default() += n;
            }
            Ok(())
        }
        Err(e) => {
            let message = e.to_string();
            conn.write(&Frame::Message(Message::Error { message })).await
        }
    }
}

/// A display's beam request, checked.
struct Request {
    /// Each beam once, with its desired rays (the last count asked for wins).
    beams: Vec<(BeamKey, u32)>,
    eye: Option<holodeck_protocol::wire::EyePoint>,
    replace: bool,
    resend: bool,
}

/// A beam request's beams, each once (the last count asked for wins), or
/// what is wrong with the request: more beams than the holodeck has, a beam
/// it does not have, an eye out of range.
fn checked_request(
    shared: &Shared,
    beams: Vec<(BeamKey, u32)>,
    eye: Option<holodeck_protocol::wire::EyePoint>,
    replace: bool,
    resend: bool,
) -> Result<Vec<(BeamKey, u32)>, String> {
    let all: usize = shared.sections.iter().map(|s| s.beam_count() as usize).sum();
    if beams.len() > all {
        return Err(format!("{} beams requested; the holodeck has {all}", beams.len()));
    }
    let beams: Vec<(BeamKey, u32)> = {
        let mut last: HashMap<BeamKey, u32> = HashMap::with_capacity(beams.len());
        let mut order = Vec::with_capacity(beams.len());
        for (k, n) in beams {
            if last.insert(k, n).is_none() {
                order.push(k);
            }
        }
        order.into_iter().map(|k| (k, last[&k])).collect()
    };
    let bad = beams.iter().find(|(k, _)| {
        shared
            .sections
            .get(k.section as usize)
            .is_none_or(|s| k.beam >= s.beam_count())
    });
    if let Some((k, _)) = bad {
        return Err(format!("no beam {} in section {}", k.beam, k.section));
    }
    Message::BeamRequest {
        beams: Vec::new(),
        eye,
        replace,
        resend,
    }
    .validate()
    .map_err(|e| e.to_string())?;
    Ok(beams)
}

/// Answers a checked request: every stored ray of its beams the display
/// does not hold yet, at once, then `Delivered`; then the request goes to
/// the scheduler, and rays that landed meanwhile are sent on the next wake.
async fn answer_request(
    conn: &mut Connection,
    shared: &Shared,
    id: u64,
    link: &DisplayLink,
    sent: &mut HashMap<BeamKey, u64>,
    r: Request,
) -> Result<(), ConnectionError> {
    // Rays that land while the beams are read are caught below
    // (and the watch ends on every path out of here).
    let watch = Watch::new(shared);
    let wanted: Vec<(BeamKey, u64)> = r
        .beams
        .iter()
        .map(|&(k, _)| {
            (
                k,
                if r.resend {
                    0
                } else {
                    sent.get(&k).copied().unwrap_or(0)
                },
            )
        })
        .collect();
    let (got, rays) = match send_beams(conn, shared, wanted.clone()).await? {
        Ok(x) => x,
        Err(e) => {
            let message = e.to_string();
            return conn.write(&Frame::Message(Message::Error { message })).await;
        }
    };
    let read: HashMap<BeamKey, u64> = got.iter().fold(HashMap::new(), |mut m, &(k, n)| {
        *m.entry(k).or_default() += n;
        m
    });
    for (k, from) in wanted {
        sent.insert(k, from + read.get(&k).copied().unwrap_or(0));
    }
    conn.write(&Frame::Message(Message::Delivered {
        beams: got.len() as u32,
        rays,
    }))
    .await?;
    let request: Vec<(BeamKey, u32, u64)> = r
        .beams
        .iter()
        .map(|&(k, desired)| (k, desired, sent.get(&k).copied().unwrap_or(0)))
        .collect();
    let keys: Vec<BeamKey> = r.beams.iter().map(|b| b.0).collect();
    let landed = watch.end(|scheduler| {
        scheduler.requests().request(id, &request, r.eye, r.replace);
        &keys
    });
    // Those rays may have missed the read (their beam was not yet
    // this display's): send what is past `sent` on the next wake.
    for k in landed {
        link.mark(k);
    }
    shared.work.notify_waiters();
    Ok(())
}

/// Answers a control command as the connection's access allows; true if it
/// was a quit that was done (the display's connection then ends).
async fn answer_control(
    conn: &mut Connection,
    shared: &Shared,
    access: Access,
    c: Control,
) -> Result<bool, ConnectionError> {
    let quit = c == Control::Quit;
    let allowed = access >= c.needs();
    let outcome = if !allowed {
        ControlOutcome::Refused {
            reason: format!("{c:?} needs {} access; this connection has {access} access", c.needs()),
        }
    } else {
        match shared.control(&c).await {
            Ok(()) => ControlOutcome::Done,
            Err(e) => ControlOutcome::Failed { error: e.to_string() },
        }
    };
    conn.write(&Frame::Message(Message::ControlReply(ControlReply {
        control: c,
        outcome,
    })))
    .await?;
    Ok(quit && allowed)
}
