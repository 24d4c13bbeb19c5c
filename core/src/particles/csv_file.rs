//! CSV particle files: a header row of property names (the PLY names, [`super::PROPERTIES`]),
//! then a row per particle.

use std::path::Path;

use super::{Defaults, Field, Partial, ParticleFileError, field_of, finish, values_of};
use crate::sim::Particle;

/// What errors call a particle of a CSV file.
const ELEMENT: &str = "row";

/// The particles of a CSV file with a header row: `bytes`, the file `path`.
pub(super) fn parse(
    path: &Path,
    bytes: &[u8],
    defaults: &Defaults,
) -> Result<Vec<Particle>, ParticleFileError> {
    let bad = |message: String| ParticleFileError::invalid(path, message);
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Err(bad("the file is empty (no header row)".to_owned()));
    }
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(bytes);
    let headers = reader
        .headers()
        .map_err(|e| bad(format!("bad header row: {e}")))?
        .clone();
    let mut columns: Vec<(Field, usize, &str)> = Vec::new();
    for (i, name) in headers.iter().enumerate() {
        if let Some(field) = field_of(name) {
            if columns.iter().any(|(f, _, _)| *f == field) {
                return Err(bad(format!(
                    "column {name} names a value another column already gave"
                )));
            }
            columns.push((field, i, name));
        }
    }
    let present: Vec<Field> = columns.iter().map(|(f, _, _)| *f).collect();
    let mut partials = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| bad(one_line(&e.to_string())))?;
        let line = record.position().map_or(0, |p| p.line());
        let mut partial = Partial::default();
        for &(field, column, name) in &columns {
            let text = record.get(column).unwrap_or("");
            let value: f64 = text.parse().map_err(|_| {
                bad(format!(
                    "{ELEMENT} {} (line {line}): property {name} = \"{text}\" is not a number",
                    partials.len()
                ))
            })?;
            partial.set(field, value);
        }
        partials.push(partial);
    }
    finish(path, ELEMENT, &present, partials, defaults, |i| {
        format!("{i} (line {})", i + 2)
    })
}

fn one_line(message: &str) -> String {
    message.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// The bytes of a CSV file holding `particles`, each f32 in its shortest exact form.
pub(super) fn encode(particles: &[Particle]) -> Result<Vec<u8>, String> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer
        .write_record(super::written_names())
        .map_err(|e| e.to_string())?;
    for p in particles {
        writer
            .write_record(values_of(p).iter().map(f32::to_string))
            .map_err(|e| e.to_string())?;
    }
    writer.into_inner().map_err(|e| e.to_string())
}
