//! Reading a recording back, message by message in the file's order (which is the robot's
//! time order within each topic), through the MCAP library's streaming reader: a file of any
//! size in bounded memory, and a file cut short (a crash, `kill -9`, a full disk) up to its last
//! whole chunk.

use std::collections::HashMap;
use std::fs::File;
use std::io::{Read, Seek};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mcap::records::Record;
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

use crate::error::RecordError;

/// One message of a recording.
#[derive(Debug, Clone)]
pub struct Message {
    /// Its topic.
    pub topic: Arc<str>,
    /// Its log time, ns on the robot's clock.
    pub time_ns: u64,
    /// Its payload (CDR).
    pub data: Vec<u8>,
}

/// A recording being read ([`Reading::open`]); an iterator of its messages.
pub struct Reading {
    path: PathBuf,
    file: File,
    reader: LinearReader,
    channels: HashMap<u16, Arc<str>>,
    /// Whether the file ended before its footer (a recording cut short): what came before
    /// its last whole chunk was read.
    pub truncated: bool,
    done: bool,
    read: u64,
}

impl Reading {
    /// Opens the recording at `path`.
    pub fn open(path: impl AsRef<Path>) -> Result<Reading, RecordError> {
        let path = path.as_ref().to_path_buf();
        let io = |what, source| RecordError::Io {
            what,
            path: path.clone(),
            source,
        };
        let mut file = File::open(&path).map_err(|e| io("opening", e))?;
        if !file.metadata().map_err(|e| io("opening", e))?.is_file() {
            return Err(RecordError::NotMcap { path });
        }
        let mut magic = [0u8; 8];
        let n = file.read(&mut magic).map_err(|e| io("reading", e))?;
        if n < magic.len() || magic != *mcap::MAGIC {
            return Err(RecordError::NotMcap { path });
        }
        file.rewind().map_err(|e| io("reading", e))?;
        // Chunks are at most a few MB (4 MiB by our writer); a corrupt length is refused
        // rather than allocated.
        let opts = LinearReaderOptions::default().with_record_length_limit(1 << 30);
        Ok(Reading {
            path,
            file,
            reader: LinearReader::new_with_options(opts),
            channels: HashMap::new(),
            truncated: false,
            done: false,
            read: 0,
        })
    }

    /// The next message, or `None` at the end (a truncated end sets [`Reading::truncated`]).
    fn next_message(&mut self) -> Result<Option<Message>, RecordError> {
        loop {
            let event = match self.reader.next_event() {
                None => return Ok(None),
                Some(Ok(e)) => e,
                // The end of a cut file: an unfinished chunk or a record the file ends in.
                Some(Err(_)) if self.read > 0 => {
                    self.truncated = true;
                    return Ok(None);
                }
                Some(Err(e)) => return Err(e.into()),
            };
            match event {
                LinearReadEvent::ReadRequest(need) => {
                    let n = self.file.read(self.reader.insert(need)).map_err(|source| {
                        RecordError::Io {
                            what: "reading",
                            path: self.path.clone(),
                            source,
                        }
                    })?;
                    self.reader.notify_read(n);
                }
                LinearReadEvent::Record { opcode, data } => {
                    match mcap::parse_record(opcode, data)? {
                        Record::Channel(c) => {
                            self.channels.insert(c.id, c.topic.as_str().into());
                        }
                        Record::Message { header, data } => {
                            let Some(topic) = self.channels.get(&header.channel_id) else {
                                continue;
                            };
                            self.read += 1;
                            return Ok(Some(Message {
                                topic: topic.clone(),
                                time_ns: header.log_time,
                                data: data.into_owned(),
                            }));
                        }
                        _ => {}
                    }
                }
            }
        }
    }
}

impl Iterator for Reading {
    type Item = Result<Message, RecordError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let r = self.next_message().transpose();
        if !matches!(r, Some(Ok(_))) {
            self.done = true;
        }
        r
    }
}
