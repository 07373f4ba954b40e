//! Reading an MCAP file's messages in order, with every record's length bounded.
//!
//! `mcap::MessageStream` trusts the lengths a file states: a damaged or hostile file whose
//! record inside a chunk claims exabytes makes it try to allocate them and abort the
//! process (found by `fuzz/fuzz_targets/recording.rs`). This reader drives mcap's
//! `LinearReader` with [`MAX_RECORD_BYTES`] instead, so such a file ends the reading where
//! the damage starts, like a file cut short.

use std::collections::HashMap;

use mcap::records::Record;
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

/// The longest record read, bytes: 64 MiB, far above anything ratf writes (chunks of
/// [`crate::recording::CHUNK_BYTES`], messages of a few KiB; mcap's default chunk is 1 MiB).
pub const MAX_RECORD_BYTES: usize = 64 * 1024 * 1024;

/// How reading ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    /// The file was whole (its footer and closing magic read).
    Complete,
    /// The file ended early or was damaged there: every message before was delivered.
    Truncated,
}

/// Call `on_message(topic, sequence, data)` for every message of the MCAP file `bytes`, in
/// file order, until the end or the first damage; `on_message`'s error stops the reading and
/// is returned.
pub fn for_each_message<E>(
    bytes: &[u8],
    mut on_message: impl FnMut(&str, u32, &[u8]) -> Result<(), E>,
) -> Result<End, E> {
    let options = LinearReaderOptions::default().with_record_length_limit(MAX_RECORD_BYTES);
    let mut reader = LinearReader::new_with_options(options);
    let mut rest = bytes;
    let mut topics: HashMap<u16, String> = HashMap::new();
    while let Some(event) = reader.next_event() {
        match event {
            Ok(LinearReadEvent::ReadRequest(need)) => {
                let n = need.min(rest.len());
                reader.insert(n).copy_from_slice(&rest[..n]);
                reader.notify_read(n);
                rest = &rest[n..];
            }
            Ok(LinearReadEvent::Record { data, opcode }) => {
                match mcap::parse_record(opcode, data) {
                    Ok(Record::Channel(channel)) => {
                        topics.insert(channel.id, channel.topic);
                    }
                    Ok(Record::Message { header, data }) => {
                        // A message must follow its channel's record.
                        let Some(topic) = topics.get(&header.channel_id) else {
                            return Ok(End::Truncated);
                        };
                        on_message(topic, header.sequence, &data)?;
                    }
                    Ok(_) => {}
                    Err(_) => return Ok(End::Truncated),
                }
            }
            Err(_) => return Ok(End::Truncated),
        }
    }
    Ok(End::Complete)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fuzzer's find, cut to what matters: a chunk whose first record claims
    /// 7 957 419 012 188 433 974 bytes. `mcap::MessageStream` aborted on it.
    #[test]
    fn a_record_claiming_exabytes_ends_the_reading_instead_of_aborting() {
        let bytes = include_bytes!("../../fuzz/corpus/recording/huge-record-length");
        let mut seen = 0;
        let end = for_each_message(bytes, |_, _, _| {
            seen += 1;
            Ok::<(), ()>(())
        });
        assert_eq!(end, Ok(End::Truncated));
        assert_eq!(seen, 0);
    }

    #[test]
    fn a_whole_file_is_complete_and_every_message_is_read_in_order() {
        let bytes = include_bytes!("../../fuzz/corpus/recording/small.mcap");
        let mut seen = Vec::new();
        let end = for_each_message(bytes, |topic, sequence, _| {
            seen.push((topic.to_owned(), sequence));
            Ok::<(), ()>(())
        });
        assert_eq!(end, Ok(End::Complete));
        let topics: Vec<&str> = seen.iter().map(|(t, _)| t.as_str()).collect();
        assert_eq!(
            topics,
            ["/ratf/session", "/sim/truth", "/sim/truth", "/sim/truth"]
        );
        assert!(seen.windows(2).all(|w| w[0].1 < w[1].1), "{seen:?}");
    }

    #[test]
    fn an_error_from_the_caller_stops_the_reading() {
        let bytes = include_bytes!("../../fuzz/corpus/recording/small.mcap");
        let mut seen = 0;
        let end = for_each_message(bytes, |_, _, _| {
            seen += 1;
            Err("stop")
        });
        assert_eq!(end, Err("stop"));
        assert_eq!(seen, 1);
    }
}
