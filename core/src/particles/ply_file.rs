//! PLY particle files through the `ply-rs-bw` crate (a maintained fork of `ply-rs`: ASCII and
//! both binary encodings, header and payload parsing). What this file adds is the mapping of
//! named vertex properties onto particles and errors that name the element and the property:
//! a truncated binary file is measured against its header before parsing, so the error can say
//! which particle and property the file ends in.

use std::path::Path;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    Addable, ElementDef, Encoding, Header, Ply, PropertyAccess, PropertyAccessResult, PropertyDef,
    PropertyType, ScalarType,
};
use ply_rs_bw::writer::Writer;

use super::{Defaults, Field, Partial, ParticleFileError, field_of, finish, values_of};
use crate::sim::Particle;

/// The element particles are read from and written as.
const ELEMENT: &str = "vertex";

/// A vertex as the parser delivers it: its scalar values in the header's property order (the
/// setters are called in that order), so that no property name is looked up per vertex. A list
/// property leaves NaN in its place.
struct RawVertex(Vec<f64>);

impl PropertyAccess for RawVertex {
    fn new() -> Self {
        Self(Vec::with_capacity(16))
    }
    fn set_property(&mut self, _: &str, _: ply_rs_bw::ply::Property) -> PropertyAccessResult {
        self.0.push(f64::NAN);
        PropertyAccessResult::Ignored
    }
    fn set_char(&mut self, _: &str, v: i8) -> PropertyAccessResult {
        self.push(v)
    }
    fn set_uchar(&mut self, _: &str, v: u8) -> PropertyAccessResult {
        self.push(v)
    }
    fn set_short(&mut self, _: &str, v: i16) -> PropertyAccessResult {
        self.push(v)
    }
    fn set_ushort(&mut self, _: &str, v: u16) -> PropertyAccessResult {
        self.push(v)
    }
    fn set_int(&mut self, _: &str, v: i32) -> PropertyAccessResult {
        self.push(v)
    }
    fn set_uint(&mut self, _: &str, v: u32) -> PropertyAccessResult {
        self.push(v)
    }
    fn set_float(&mut self, _: &str, v: f32) -> PropertyAccessResult {
        self.push(v)
    }
    fn set_double(&mut self, _: &str, v: f64) -> PropertyAccessResult {
        self.push(v)
    }
}

impl RawVertex {
    fn push(&mut self, v: impl Into<f64>) -> PropertyAccessResult {
        self.0.push(v.into());
        PropertyAccessResult::Set
    }
}

/// Bytes of one binary scalar.
fn scalar_bytes(t: &ScalarType) -> usize {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// The scale that maps an integer colour channel to [0, 1] (Blender writes `uchar` colours).
fn colour_scale(t: &ScalarType) -> f64 {
    match t {
        ScalarType::UChar => 1.0 / 255.0,
        ScalarType::UShort => 1.0 / 65535.0,
        _ => 1.0,
    }
}

/// Byte length of the header, up to and including the `end_header` line.
fn header_len(bytes: &[u8]) -> Option<usize> {
    let at = bytes
        .windows(b"end_header".len())
        .position(|w| w == b"end_header")?;
    let newline = bytes[at..].iter().position(|&b| b == b'\n')?;
    Some(at + newline + 1)
}

/// For a binary file: checks that the payload holds every element before and including the
/// vertices, and names the particle and property where it ends if not. Elements with list
/// properties have no fixed size; past one of them, the parser's own error is all there is.
fn check_binary_length(
    path: &Path,
    header: &Header,
    payload: usize,
) -> Result<(), ParticleFileError> {
    let mut offset = 0usize;
    for element in header.elements.values() {
        let mut sizes = Vec::new();
        for p in element.properties.values() {
            match &p.data_type {
                PropertyType::Scalar(t) => sizes.push((p.name.as_str(), scalar_bytes(t))),
                PropertyType::List(..) => return Ok(()),
            }
        }
        let stride: usize = sizes.iter().map(|(_, s)| s).sum();
        let need = stride.saturating_mul(element.count);
        if payload < offset + need {
            let into = payload - offset;
            let (index, mut within) = (into / stride.max(1), into % stride.max(1));
            let property = sizes
                .iter()
                .find(|(_, size)| {
                    let here = within < *size;
                    within = within.saturating_sub(*size);
                    here
                })
                .map_or("?", |(name, _)| name);
            return Err(ParticleFileError::invalid(
                path,
                format!(
                    "element {} {index} of {}: property {property}: the file ends there (a truncated binary PLY: {} of {} payload bytes)",
                    element.name,
                    element.count,
                    payload,
                    offset + need
                ),
            ));
        }
        if element.name == ELEMENT {
            return Ok(());
        }
        offset += need;
    }
    Ok(())
}

/// The particles of a PLY file (ASCII or binary): `bytes`, the file `path`.
pub(super) fn parse(
    path: &Path,
    bytes: &[u8],
    defaults: &Defaults,
) -> Result<Vec<Particle>, ParticleFileError> {
    let bad = |message: String| ParticleFileError::invalid(path, message);
    if bytes.is_empty() {
        return Err(bad("the file is empty (not a PLY file)".to_owned()));
    }
    if !bytes.starts_with(b"ply") {
        return Err(bad(
            "not a PLY file: it does not start with the line \"ply\"".to_owned(),
        ));
    }
    let parser = Parser::<RawVertex>::new();
    let mut reader = Reader::new(std::io::BufReader::new(bytes));
    let header = parser
        .read_header(&mut reader)
        .map_err(|e| bad(format!("bad header: {}", one_line(&e.to_string()))))?;
    let vertex = header.elements.get(ELEMENT).ok_or_else(|| {
        let names: Vec<&str> = header.elements.keys().map(String::as_str).collect();
        bad(format!(
            "no element {ELEMENT} (the particles); its elements: {}",
            if names.is_empty() {
                "none".to_owned()
            } else {
                names.join(", ")
            }
        ))
    })?;
    // Which column of a vertex each field is read from, and the colour channels' scale.
    let mut columns: Vec<(Field, usize, f64)> = Vec::new();
    for (i, p) in vertex.properties.values().enumerate() {
        let Some(field) = field_of(&p.name) else {
            continue;
        };
        let scale = match &p.data_type {
            PropertyType::Scalar(t) => match field {
                Field::Red | Field::Green | Field::Blue => colour_scale(t),
                _ => 1.0,
            },
            PropertyType::List(..) => {
                return Err(bad(format!(
                    "element {ELEMENT}: property {} is a list; it must be a number",
                    p.name
                )));
            }
        };
        if columns.iter().any(|(f, _, _)| *f == field) {
            return Err(bad(format!(
                "element {ELEMENT}: property {} names a value another property already gave",
                p.name
            )));
        }
        columns.push((field, i, scale));
    }
    if header.encoding != Encoding::Ascii {
        let start = header_len(bytes).ok_or_else(|| bad("no end_header line".to_owned()))?;
        check_binary_length(path, &header, bytes.len() - start)?;
    }
    let payload = parser
        .read_payload(&mut reader, &header)
        .map_err(|e| bad(format!("element {ELEMENT}: {}", one_line(&e.to_string()))))?;
    let raw = payload.get(ELEMENT).map(Vec::as_slice).unwrap_or(&[]);
    let partials = raw
        .iter()
        .map(|v| {
            let mut partial = Partial::default();
            for &(field, column, scale) in &columns {
                if let Some(&value) = v.0.get(column) {
                    partial.set(field, value * scale);
                }
            }
            partial
        })
        .collect();
    let present: Vec<Field> = columns.iter().map(|(f, _, _)| *f).collect();
    finish(path, ELEMENT, &present, partials, defaults, |i| {
        i.to_string()
    })
}

/// The parser's messages may span lines; ours are one.
fn one_line(message: &str) -> String {
    message.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// A particle for the writer: its values in [`super::PROPERTIES`] order.
struct OutVertex([f32; 12]);

impl PropertyAccess for OutVertex {
    fn new() -> Self {
        Self([0.0; 12])
    }
    fn get_float(&self, name: &str) -> Option<f32> {
        field_of(name).map(|f| self.0[f as usize])
    }
}

/// The bytes of a PLY file holding `particles` as float vertex properties named as
/// [`super::written_names`].
pub(super) fn encode(particles: &[Particle], ascii: bool) -> Result<Vec<u8>, String> {
    let mut ply = Ply::<OutVertex>::new();
    ply.header.encoding = match ascii {
        true => Encoding::Ascii,
        false => Encoding::BinaryLittleEndian,
    };
    ply.header.comments.push(format!(
        "smokeshadow {} particles: position (m), radius (m), density = extinction (1/m), albedo (linear RGB), age (s), velocity (m/s)",
        env!("CARGO_PKG_VERSION")
    ));
    let mut element = ElementDef::new(ELEMENT.to_owned());
    for name in super::written_names() {
        element.properties.add(PropertyDef::new(
            name.to_owned(),
            PropertyType::Scalar(ScalarType::Float),
        ));
    }
    ply.header.elements.add(element);
    ply.payload.insert(
        ELEMENT.to_owned(),
        particles.iter().map(|p| OutVertex(values_of(p))).collect(),
    );
    let mut out = Vec::new();
    Writer::new()
        .write_ply(&mut out, &mut ply)
        .map_err(|e| e.to_string())?;
    Ok(out)
}
