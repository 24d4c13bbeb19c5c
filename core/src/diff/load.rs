//! Reading the images a diff compares: PNG only, any bit depth and colour type, flattened to
//! 8-bit sRGB RGB. The renderer writes opaque 8-bit RGB PNGs; anything else (a baseline edited in
//! a paint program, a 16-bit export, an image with alpha) is converted here, once, so that every
//! metric sees the same pixels.

use std::path::Path;

use image::{DynamicImage, ImageFormat, RgbImage};

use super::DiffError;

/// The eight bytes every PNG file starts with (PNG specification, section 5.2).
const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

/// Loads a PNG as 8-bit RGB.
///
/// - 8-bit RGB is taken as is; grey images are expanded to RGB.
/// - 16-bit images are rounded to 8 bits per channel.
/// - An alpha channel is **composited over black** (colour x alpha), then dropped: smokeshadow's
///   renders are opaque, so a transparent pixel in a baseline can only mean "nothing there".
///
/// The values are taken to be sRGB-encoded whatever the file's colour chunks say.
///
/// `bytes` are the file `path` (which errors name). Errors: the bytes do not start with the
/// PNG signature ([`DiffError::NotPng`]), or do not decode ([`DiffError::CorruptPng`]).
pub fn decode_png(path: &Path, bytes: &[u8]) -> Result<RgbImage, DiffError> {
    if !bytes.starts_with(&PNG_SIGNATURE) {
        return Err(DiffError::NotPng {
            path: path.to_owned(),
        });
    }
    let decoded = image::load_from_memory_with_format(bytes, ImageFormat::Png).map_err(|err| {
        DiffError::CorruptPng {
            path: path.to_owned(),
            reason: err.to_string().replace('\n', " "),
        }
    })?;
    Ok(flatten_to_rgb8(decoded))
}

/// Checks that a reference and a test image have the same size; the size error names both
/// files (`reference`, `test`) and both sizes.
pub fn same_size(
    reference: (&Path, RgbImage),
    test: (&Path, RgbImage),
) -> Result<(RgbImage, RgbImage), DiffError> {
    if reference.1.dimensions() != test.1.dimensions() {
        return Err(DiffError::SizeMismatch {
            reference: format!("reference {}", reference.0.display()),
            reference_size_px: reference.1.dimensions(),
            test: format!("test {}", test.0.display()),
            test_size_px: test.1.dimensions(),
        });
    }
    Ok((reference.1, test.1))
}

/// Converts any decoded image to 8-bit RGB, compositing alpha over black.
fn flatten_to_rgb8(image: DynamicImage) -> RgbImage {
    if !image.color().has_alpha() {
        return image.into_rgb8();
    }
    // Composite in floating point so that 16-bit alpha keeps its precision; an opaque pixel
    // (alpha exactly 1) round-trips to its original 8-bit value.
    let rgba = image.into_rgba32f();
    let mut out = RgbImage::new(rgba.width(), rgba.height());
    for (src, dst) in rgba.pixels().zip(out.pixels_mut()) {
        let [r, g, b, a] = src.0;
        let quantize = |c: f32| ((c * a).clamp(0.0, 1.0) * 255.0).round() as u8;
        dst.0 = [quantize(r), quantize(g), quantize(b)];
    }
    out
}
