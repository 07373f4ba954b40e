//! The organisers' UDP protocol (`ratf_core::referee::protocol`) on any datagram: a request
//! the mock server recognises and a reply the robot accepts both print back to text that
//! parses to the same thing, and every refused reply says which request it answered.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ratf_core::referee::protocol::{Request, parse_reply};

fuzz_target!(|datagram: &[u8]| {
    if let Some(request) = Request::parse(datagram) {
        assert_eq!(Request::parse(request.as_str().as_bytes()), Some(request));
    }
    for request in Request::ALL {
        match parse_reply(request, datagram) {
            Ok(reply) => {
                let text = reply.to_text();
                assert_eq!(
                    parse_reply(request, text.as_bytes()),
                    Ok(reply),
                    "{text:?} for {request}"
                );
            }
            Err(error) => assert!(
                error.to_string().contains(request.as_str()),
                "{error} does not name {request}"
            ),
        }
    }
});
