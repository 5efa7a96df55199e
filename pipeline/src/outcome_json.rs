//! The JSON objects that end a command under `--log-format json`: every one carries the same
//! fields, null where they do not apply. A leaf, so that `progress` can print the summary
//! without depending on how errors are classified.

use serde_json::{json, Value};

/// The final summary of a successful run as one JSON object.
pub fn summary_json(seconds: f64, counts: Value) -> Value {
    let mut object = fields("done", seconds);
    object["kind"] = "success".into();
    object["exit_code"] = reducem::exit_code::SUCCESS.into();
    object["stage"] = "run".into();
    object["counts"] = counts;
    object
}

/// Every field of the contract, null until known.
pub fn fields(event: &str, seconds: f64) -> Value {
    json!({
        "time": crate::time::unix_time(),
        "event": event,
        "kind": null, "file": null, "element": null, "index": null, "offset": null,
        "line": null, "stage": null, "chunk": null, "counts": null, "seconds": seconds,
    })
}
