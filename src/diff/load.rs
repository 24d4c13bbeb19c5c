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
/// Errors: the file cannot be read ([`DiffError::Read`]), does not start with the PNG signature
/// ([`DiffError::NotPng`]), or does not decode ([`DiffError::CorruptPng`]).
pub fn load_png(path: &Path) -> Result<RgbImage, DiffError> {
    let bytes = std::fs::read(path).map_err(|cause| DiffError::Read {
        path: path.to_owned(),
        cause,
    })?;
    if !bytes.starts_with(&PNG_SIGNATURE) {
        return Err(DiffError::NotPng {
            path: path.to_owned(),
        });
    }
    let decoded = image::load_from_memory_with_format(&bytes, ImageFormat::Png).map_err(|err| {
        DiffError::CorruptPng {
            path: path.to_owned(),
            reason: err.to_string().replace('\n', " "),
        }
    })?;
    Ok(flatten_to_rgb8(decoded))
}

/// Loads a reference and a test image and checks that they have the same size; the size error
/// names both files and both sizes.
pub fn load_pair(reference: &Path, test: &Path) -> Result<(RgbImage, RgbImage), DiffError> {
    let reference_image = load_png(reference)?;
    let test_image = load_png(test)?;
    if reference_image.dimensions() != test_image.dimensions() {
        return Err(DiffError::SizeMismatch {
            reference: format!("reference {}", reference.display()),
            reference_size_px: reference_image.dimensions(),
            test: format!("test {}", test.display()),
            test_size_px: test_image.dimensions(),
        });
    }
    Ok((reference_image, test_image))
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

#[cfg(test)]
mod tests {
    use super::*;
    use image::{ImageBuffer, Rgba, RgbaImage};

    fn scratch_dir(name: &str) -> std::path::PathBuf {
        let dir =
            std::env::temp_dir().join(format!("smokeshadow-diff-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn alpha_is_composited_over_black_and_16_bit_is_rounded() {
        let dir = scratch_dir("load");
        let rgba = RgbaImage::from_fn(2, 1, |x, _| {
            if x == 0 {
                Rgba([200, 100, 50, 255])
            } else {
                Rgba([200, 100, 50, 51])
            }
        });
        let path = dir.join("rgba.png");
        rgba.save(&path).unwrap();
        let rgb = load_png(&path).unwrap();
        assert_eq!(rgb.get_pixel(0, 0).0, [200, 100, 50]);
        // 51/255 = 0.2 alpha: 200 * 0.2 = 40, 100 * 0.2 = 20, 50 * 0.2 = 10.
        assert_eq!(rgb.get_pixel(1, 0).0, [40, 20, 10]);

        let deep: ImageBuffer<image::Rgb<u16>, Vec<u16>> =
            ImageBuffer::from_pixel(1, 1, image::Rgb([65535, 257 * 128, 0]));
        let path16 = dir.join("deep.png");
        DynamicImage::ImageRgb16(deep).save(&path16).unwrap();
        assert_eq!(load_png(&path16).unwrap().get_pixel(0, 0).0, [255, 128, 0]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn non_png_and_corrupt_png_are_told_apart() {
        let dir = scratch_dir("bad");
        let text = dir.join("text.png");
        std::fs::write(&text, b"hello, not an image").unwrap();
        let err = load_png(&text).unwrap_err().to_string();
        assert!(
            err.contains("not a PNG") && err.contains("text.png"),
            "{err}"
        );

        let truncated = dir.join("truncated.png");
        let mut bytes = PNG_SIGNATURE.to_vec();
        bytes.extend_from_slice(b"\0\0\0\x0dIHDR garbage");
        std::fs::write(&truncated, bytes).unwrap();
        let err = load_png(&truncated).unwrap_err().to_string();
        assert!(
            err.contains("corrupt") && err.contains("truncated.png"),
            "{err}"
        );
        assert!(!err.contains('\n'), "{err}");

        let missing = dir.join("missing.png");
        let err = load_png(&missing).unwrap_err().to_string();
        assert!(
            err.contains("cannot read") && err.contains("missing.png"),
            "{err}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
