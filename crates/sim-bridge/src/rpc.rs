//! The answer every simulated RPC service gives to one request: its dispatch's data with status OK, or the refusal
//! code with no data, echoing the request's identity; nothing when the caller asked for no reply.
use unitree_idl::api::{status, Request_, ResponseHeader_, ResponseStatus_, Response_};

/// The response to `request` given its dispatch's `result`; `refused` counts refusals (replied or not).
pub(crate) fn answer(request: &Request_, result: Result<String, i32>, refused: &mut u64) -> Option<Response_> {
    let (code, data) = match result {
        Ok(data) => (status::OK, data),
        Err(code) => {
            *refused += 1;
            (code, String::new())
        }
    };
    if request.header.policy.noreply {
        return None;
    }
    Some(Response_ {
        header: ResponseHeader_ { identity: request.header.identity.clone(), status: ResponseStatus_ { code } },
        data,
        binary: Vec::new(),
    })
}
