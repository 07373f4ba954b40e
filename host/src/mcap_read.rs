//! Reading an MCAP file's messages in order, with every record's length bounded.
//!
//! `mcap::MessageStream` trusts the lengths a file states: a damaged or hostile file whose
//! record inside a chunk claims exabytes makes it try to allocate them and abort the
//! process (found by `fuzz/fuzz_targets/recording.rs`). This reader drives mcap's
//! `LinearReader` with [`MAX_RECORD_BYTES`] instead, so such a file ends the reading where
//! the damage starts, like a file cut short. It also stops before an uncompressed chunk
//! whose records overrun the chunk, on which mcap's reader overflows a subtraction (a panic
//! where overflow checks are on; also found by the fuzz target). It parses only the channel
//! and message records it needs: mcap's parser of a damaged attachment record slices past
//! the record's end and panics (found by the fuzz target in CI).

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
    let safe = safe_prefix(bytes);
    let mut rest = &bytes[..safe];
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
                if opcode != CHANNEL_OPCODE && opcode != MESSAGE_OPCODE {
                    continue;
                }
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
    Ok(if safe < bytes.len() {
        End::Truncated
    } else {
        End::Complete
    })
}

/// The MCAP channel record's opcode.
const CHANNEL_OPCODE: u8 = 0x04;

/// The MCAP message record's opcode.
const MESSAGE_OPCODE: u8 = 0x05;

/// The MCAP chunk record's opcode.
const CHUNK_OPCODE: u8 = 0x06;

/// Bytes of the magic that opens an MCAP file.
const MAGIC_LEN: usize = 8;

/// Bytes of a record's opcode and length.
const RECORD_HEADER_LEN: usize = 9;

fn u64_at(bytes: &[u8], at: usize) -> Option<u64> {
    let end = at.checked_add(8)?;
    Some(u64::from_le_bytes(bytes.get(at..end)?.try_into().ok()?))
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    let end = at.checked_add(4)?;
    Some(u32::from_le_bytes(bytes.get(at..end)?.try_into().ok()?))
}

/// The length of the start of `bytes` that holds no uncompressed chunk whose records
/// overrun it (all of `bytes` when there is none). A chunk cut by the end of the file is
/// checked as far as it goes.
fn safe_prefix(bytes: &[u8]) -> usize {
    let mut at = MAGIC_LEN;
    loop {
        let Some(&opcode) = bytes.get(at) else {
            return bytes.len();
        };
        let Some(len) = u64_at(bytes, at + 1).and_then(|len| usize::try_from(len).ok()) else {
            return bytes.len();
        };
        let body_start = at + RECORD_HEADER_LEN;
        let end = body_start.saturating_add(len);
        let body = bytes.get(body_start..end.min(bytes.len())).unwrap_or(&[]);
        if opcode == CHUNK_OPCODE && !chunk_records_fit(body) {
            return at;
        }
        if end >= bytes.len() {
            return bytes.len();
        }
        at = end;
    }
}

/// False for an uncompressed chunk (`body`, possibly cut by the end of the file) with a
/// record that overruns the chunk's records field, or whose header is short; true for every
/// compressed chunk (its records are checked as decompressed).
fn chunk_records_fit(body: &[u8]) -> bool {
    // message_start_time, message_end_time, uncompressed_size (u64 each), uncompressed_crc
    // (u32), then the compression's name (u32 length + text) and the records (u64 length +
    // bytes).
    let Some(name_len) = u32_at(body, 28).and_then(|n| usize::try_from(n).ok()) else {
        return false;
    };
    let Some(records_at) = 32usize.checked_add(name_len) else {
        return false;
    };
    if name_len > 0 {
        return true;
    }
    let Some(declared) = u64_at(body, records_at).and_then(|n| usize::try_from(n).ok()) else {
        return false;
    };
    let present = body.get(records_at + 8..).unwrap_or(&[]);
    let records = &present[..present.len().min(declared)];
    let mut at = 0;
    while at < records.len() {
        if at + RECORD_HEADER_LEN > declared {
            return false;
        }
        let Some(len) = u64_at(records, at + 1).and_then(|n| usize::try_from(n).ok()) else {
            // Cut by the end of the file inside this header: nothing more to read.
            return true;
        };
        match (at + RECORD_HEADER_LEN).checked_add(len) {
            Some(end) if end <= declared => at = end,
            _ => return false,
        }
    }
    true
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

    /// The fuzzer's second find: an uncompressed chunk whose record claims more bytes than
    /// the chunk holds; mcap's reader subtracted past zero there.
    /// Found by `fuzz/fuzz_targets/recording.rs` in CI: an attachment record whose inner
    /// lengths overrun it made mcap's `parse_record` panic.
    #[test]
    fn a_damaged_attachment_is_skipped_not_parsed() {
        let bytes: &[u8] = &[
            137, 77, 67, 65, 80, 48, 13, 10, 9, 37, 0, 0, 0, 0, 0, 0, 0, 0, 137, 77, 67, 65, 80,
            239, 116, 172, 0, 0, 0, 42, 1, 0, 0, 0, 0, 0, 0, 4, 0, 0, 0, 0, 0, 114, 97, 116, 38,
            32, 48, 0, 0, 0, 0, 62, 202, 204, 64, 46, 49, 46, 48, 6, 143, 59, 0, 0, 0, 0, 0, 0, 0,
            1, 0, 0, 0, 0, 0, 0, 0, 1, 115, 116, 116, 98, 33, 0, 0, 0, 0, 0, 0, 0, 1, 150, 0, 1, 0,
            13, 188, 80, 0, 0, 237, 44, 173,
        ];
        let mut messages = 0;
        let end = for_each_message(bytes, |_, _, _| {
            messages += 1;
            Ok::<(), ()>(())
        })
        .unwrap();
        assert_eq!((end, messages), (End::Truncated, 0));
    }

    #[test]
    fn an_uncompressed_chunk_overrun_by_its_records_ends_the_reading() {
        let bytes = include_bytes!("../../fuzz/corpus/recording/chunk-overrun");
        let end = for_each_message(bytes, |_, _, _| Ok::<(), ()>(()));
        assert_eq!(end, Ok(End::Truncated));
        assert!(safe_prefix(bytes) < bytes.len());
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
