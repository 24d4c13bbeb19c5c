//! Numbered file sequences (`smoke.%04d.ply`, `smoke.%04d.vdb`): a pattern's frame names and
//! the frame a scene time picks, for particle and volume sequences alike.

/// Whether a file name is a numbered sequence's pattern (`smoke.%04d.ply`).
pub fn is_sequence(pattern: &str) -> bool {
    sequence_spec(pattern).is_some()
}

/// The `%d` / `%0Nd` in a pattern: its byte range and zero-padded width.
fn sequence_spec(pattern: &str) -> Option<(std::ops::Range<usize>, usize)> {
    let start = pattern.find('%')?;
    let rest = &pattern[start + 1..];
    let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
    if rest.as_bytes().get(digits) != Some(&b'd') {
        return None;
    }
    let width = rest[..digits].parse().unwrap_or(0);
    Some((start..start + 1 + digits + 1, width))
}

/// A sequence pattern's file name for `frame` (`smoke.%04d.ply`, 7 -> `smoke.0007.ply`); a name
/// without a `%d` is returned as it is.
pub fn frame_name(pattern: &str, frame: i64) -> String {
    match sequence_spec(pattern) {
        Some((range, width)) => format!(
            "{}{frame:0width$}{}",
            &pattern[..range.start],
            &pattern[range.end..]
        ),
        None => pattern.to_owned(),
    }
}

/// A sequence's frame at scene time `time_s`: `frame_at_zero` + the nearest whole number of
/// frames at `frame_rate_hz` (particle and volume sequences alike).
pub fn sequence_frame(frame_at_zero: i64, frame_rate_hz: f32, time_s: f32) -> i64 {
    frame_at_zero + (f64::from(time_s) * f64::from(frame_rate_hz)).round() as i64
}
