//! Where a walkthrough's samples come from: a holodeck server (a live
//! session, whose samplers trace what the view asks for) or a holodeck file
//! read directly (display-only replay, no server). The window works the same
//! over both.

use std::time::Instant;

use holodeck_protocol::wire::{Control, Progress};
use holodeck_protocol::{BeamKey, RayRecord, Section};

use crate::client::{ClientError, DisplaySession};
use crate::request::BeamRequest;
use crate::sample::{Sample, SampleDecoder};

/// What a source hands the window's driver.
pub enum Delivery<'a> {
    /// Decoded samples (a server's, as they arrive).
    Samples(&'a [Sample]),
    /// Stored records of whole beams, in chunks, with what decodes them (a
    /// file's): the driver decodes them as it projects them
    /// ([`crate::Driver::add_beams`]), as `holodeck pict` does.
    Beams(&'a SampleDecoder, &'a [&'a [(BeamKey, &'a [RayRecord])]]),
}

/// Why a source failed.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// The server connection failed.
    #[error(transparent)]
    Client(#[from] ClientError),
    /// Reading a holodeck file failed (the message names the file).
    #[error("{0}")]
    File(String),
    /// The command needs a server and there is none.
    #[error("{0} needs a server: this is a replay of a file")]
    NoServer(String),
}

/// A supplier of samples for the views a display walks through.
pub trait Source {
    /// The holodeck's sections.
    fn sections(&self) -> &[Section];
    /// Asks for a view's beams (replacing the last request) and hands the
    /// stored samples not sent before (all of them with `resend`) to `sink`;
    /// returns how many.
    fn request(
        &mut self,
        request: &BeamRequest,
        resend: bool,
        sink: &mut dyn FnMut(Delivery<'_>),
    ) -> Result<u64, SourceError>;
    /// Hands the stored samples of `beams` (the neighbours of a view's
    /// beams, for its pixels without a ray: [`crate::gaps`]) to `sink`,
    /// without counting them as given, so that a later view that sees one
    /// of these beams takes all of its rays; returns how many. Nothing is
    /// asked traced. A source that cannot (a server, whose protocol hands
    /// each stored ray to a display once) hands none.
    fn neighbours(&mut self, beams: &[BeamKey], sink: &mut dyn FnMut(Delivery<'_>)) -> Result<u64, SourceError>;
    /// Raises the counts of the current view's beams (more samples wanted).
    fn raise(&mut self, request: &BeamRequest) -> Result<(), SourceError>;
    /// Hands newly traced samples to `sink` until `deadline`; returns how many.
    fn poll(&mut self, deadline: Instant, sink: &mut dyn FnMut(&[Sample])) -> Result<u64, SourceError>;
    /// Samples of `key` received (since the last resend).
    fn received(&self, key: BeamKey) -> u64;
    /// Sends a command to the server.
    fn control(&mut self, control: Control) -> Result<(), SourceError>;
    /// The server's last report, if it sends them.
    fn status(&self) -> Option<Progress>;
    /// Messages for the user that came since the last call (answers to
    /// commands, refusals).
    fn notices(&mut self) -> Vec<String>;
    /// A short name for the window's title.
    fn name(&self) -> String;
}

/// A live session with a holodeck server.
pub struct ServerSource {
    session: DisplaySession,
    name: String,
}

impl ServerSource {
    /// Wraps a connected session; `name` is the server's address.
    pub fn new(session: DisplaySession, name: String) -> ServerSource {
        ServerSource { session, name }
    }
}

impl Source for ServerSource {
    fn sections(&self) -> &[Section] {
        self.session.sections()
    }

    fn request(
        &mut self,
        request: &BeamRequest,
        resend: bool,
        sink: &mut dyn FnMut(Delivery<'_>),
    ) -> Result<u64, SourceError> {
        Ok(self
            .session
            .request(request, resend, &mut |s: &[Sample]| sink(Delivery::Samples(s)))?
            .samples)
    }

    fn neighbours(&mut self, _beams: &[BeamKey], _sink: &mut dyn FnMut(Delivery<'_>)) -> Result<u64, SourceError> {
        Ok(0)
    }

    fn raise(&mut self, request: &BeamRequest) -> Result<(), SourceError> {
        Ok(self.session.raise(request)?)
    }

    fn poll(&mut self, deadline: Instant, sink: &mut dyn FnMut(&[Sample])) -> Result<u64, SourceError> {
        Ok(self.session.refine(deadline, sink)?)
    }

    fn received(&self, key: BeamKey) -> u64 {
        self.session.received(key)
    }

    fn control(&mut self, control: Control) -> Result<(), SourceError> {
        Ok(self.session.control(control)?)
    }

    fn status(&self) -> Option<Progress> {
        self.session.progress().copied()
    }

    fn notices(&mut self) -> Vec<String> {
        self.session
            .take_notices()
            .into_iter()
            // "pause done", "clobber was refused: ..." (the outcome reads on from the command's name).
            .map(|r| match r.outcome {
                holodeck_protocol::wire::ControlOutcome::Done => format!("{} done", command_name(&r.control)),
                ref other => format!("{} {other}", command_name(&r.control)),
            })
            .collect()
    }

    fn name(&self) -> String {
        format!("{} ({})", self.name, self.session.access())
    }
}

pub use crate::command::command_name;
