//! Frames' GPU pass times as a Chrome trace event file (the JSON object format), which Perfetto
//! (ui.perfetto.dev) and chrome://tracing open: one complete event ("ph": "X") per frame and one
//! per pass inside it, on the GPU's own clock, so that the gaps between frames are real.

use serde_json::{Value, json};

use super::PassTimes;

/// The trace of `frames` (in the order they ran); `title` names the process row (technique,
/// budget, scene). Frames without a start mark (no timestamp queries) are left out.
pub fn chrome_trace(frames: &[PassTimes], title: &str) -> Value {
    let first = frames.iter().find_map(|f| f.start_ms).unwrap_or(0.0);
    let us = |ms: f64| ms * 1e3;
    let mut events = vec![
        json!({"name": "process_name", "ph": "M", "pid": 1, "args": {"name": title}}),
        json!({"name": "thread_name", "ph": "M", "pid": 1, "tid": 1, "args": {"name": "GPU frames"}}),
        json!({"name": "thread_name", "ph": "M", "pid": 1, "tid": 2, "args": {"name": "GPU passes"}}),
    ];
    for (i, frame) in frames.iter().enumerate() {
        let Some(start) = frame.start_ms else {
            continue;
        };
        let origin = start - first;
        events.push(json!({
            "name": format!("frame {i}"),
            "cat": "frame",
            "ph": "X",
            "pid": 1,
            "tid": 1,
            "ts": us(origin),
            "dur": us(frame.total_ms()),
        }));
        for span in &frame.spans {
            events.push(json!({
                "name": span.name,
                "cat": "pass",
                "ph": "X",
                "pid": 1,
                "tid": 2,
                "ts": us(origin + span.start_ms),
                "dur": us(span.ms),
                "args": {"frame": i},
            }));
        }
    }
    json!({"traceEvents": events, "displayTimeUnit": "ms"})
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::PassSpan;

    fn frame(start_ms: f64, spans: &[(&'static str, f64, f64)]) -> PassTimes {
        let mut passes: Vec<(&'static str, f64)> = Vec::new();
        for &(name, _, ms) in spans {
            match passes.iter_mut().find(|(n, _)| *n == name) {
                Some((_, t)) => *t += ms,
                None => passes.push((name, ms)),
            }
        }
        PassTimes {
            passes,
            spans: spans
                .iter()
                .map(|&(name, start_ms, ms)| PassSpan { name, start_ms, ms })
                .collect(),
            start_ms: Some(start_ms),
        }
    }

    #[test]
    fn frames_and_passes_lie_on_one_timeline() {
        let frames = [
            frame(1000.0, &[("shadow", 0.0, 2.0), ("particles", 2.0, 3.0)]),
            frame(1010.0, &[("shadow", 0.0, 2.5), ("particles", 2.5, 3.0)]),
        ];
        let trace = chrome_trace(&frames, "osm");
        let events = trace["traceEvents"].as_array().unwrap();
        let complete: Vec<&Value> = events.iter().filter(|e| e["ph"] == "X").collect();
        assert_eq!(complete.len(), 6);
        let at = |name: &str, frame: u64| {
            complete
                .iter()
                .find(|e| e["name"] == name && e["args"]["frame"] == frame)
                .map(|e| (e["ts"].as_f64().unwrap(), e["dur"].as_f64().unwrap()))
                .unwrap()
        };
        assert_eq!(at("particles", 0), (2000.0, 3000.0));
        assert_eq!(at("shadow", 1), (10000.0, 2500.0));
        let second = complete.iter().find(|e| e["name"] == "frame 1").unwrap();
        assert_eq!(second["ts"].as_f64(), Some(10000.0));
        assert_eq!(second["dur"].as_f64(), Some(5500.0));
    }
}
