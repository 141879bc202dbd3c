//! Replay straight from a holodeck file into the walkthrough window: a
//! [`Source`] whose requests read the stored rays of their beams that were
//! not handed out yet. Nothing new ever arrives, and there is no server to
//! command. (With the `window` feature.)

use std::collections::HashMap;
use std::time::Instant;

use holodeck_display::request::BeamRequest;
use holodeck_display::window::{Delivery, Source, SourceError};
use holodeck_display::{Sample, SampleDecoder};
use holodeck_file::HoloFile;
use holodeck_protocol::wire::Control;
use holodeck_protocol::{BeamKey, Section};

/// Samples straight from a holodeck file: a request reads the stored rays
/// of its beams that were not handed out yet; nothing new ever arrives, and
/// there is no server to command.
pub struct FileSource {
    file: HoloFile,
    name: String,
    decoder: SampleDecoder,
    sent: HashMap<BeamKey, u64>,
}

impl FileSource {
    /// Replays `file` (opened read-only), named `name` in the title.
    pub fn new(file: HoloFile, name: String) -> FileSource {
        let decoder = SampleDecoder::new(file.sections().to_vec());
        FileSource {
            file,
            name,
            decoder,
            sent: HashMap::new(),
        }
    }
}

impl Source for FileSource {
    fn sections(&self) -> &[Section] {
        self.decoder.sections()
    }

    fn request(
        &mut self,
        request: &BeamRequest,
        resend: bool,
        sink: &mut dyn FnMut(Delivery<'_>),
    ) -> Result<u64, SourceError> {
        if resend {
            self.sent.clear();
        }
        // Records past those sent, in the chunks `holodeck pict` cuts, so
        // that a view drawn whole is the picture `pict` draws; a beam counts
        // as sent once its records are handed over.
        let mut keys: Vec<BeamKey> = request.beams.iter().map(|b| b.0).collect();
        keys.sort_unstable();
        let decoder = &self.decoder;
        let read = crate::recall::read_unsent(&mut self.file, &keys, &mut self.sent, |chunks| {
            sink(Delivery::Beams(decoder, chunks))
        });
        read.map_err(|e| SourceError::File(format!("{}: {e}", self.name)))
    }

    fn neighbours(&mut self, beams: &[BeamKey], sink: &mut dyn FnMut(Delivery<'_>)) -> Result<u64, SourceError> {
        let decoder = &self.decoder;
        let read = crate::recall::read_in_chunks(
            &mut self.file,
            beams,
            |_, _| 0,
            |chunks| sink(Delivery::Beams(decoder, chunks)),
        );
        read.map_err(|e| SourceError::File(format!("{}: {e}", self.name)))
    }

    fn raise(&mut self, _request: &BeamRequest) -> Result<(), SourceError> {
        Ok(())
    }

    fn poll(&mut self, _deadline: Instant, _sink: &mut dyn FnMut(&[Sample])) -> Result<u64, SourceError> {
        Ok(0)
    }

    fn received(&self, key: BeamKey) -> u64 {
        self.sent.get(&key).copied().unwrap_or(0)
    }

    fn control(&mut self, control: Control) -> Result<(), SourceError> {
        Err(SourceError::NoServer(format!("{control:?}")))
    }

    fn status(&self) -> Option<holodeck_protocol::wire::Progress> {
        None
    }

    fn notices(&mut self) -> Vec<String> {
        Vec::new()
    }

    fn name(&self) -> String {
        self.name.clone()
    }
}
