//! Image differences ([`smokeshadow_core::diff`]), and the PNG files the CLI compares read from
//! the disk.

use std::path::Path;

use image::RgbImage;
pub use smokeshadow_core::diff::*;

/// Loads a PNG file as 8-bit RGB ([`decode_png`]). Errors: the file cannot be read
/// ([`DiffError::Read`]), or is not a PNG it can decode.
pub fn load_png(path: &Path) -> Result<RgbImage, DiffError> {
    let bytes = std::fs::read(path).map_err(|cause| DiffError::Read {
        path: path.to_owned(),
        cause,
    })?;
    decode_png(path, &bytes)
}

/// Loads a reference and a test image and checks that they have the same size; the size error
/// names both files and both sizes.
pub fn load_pair(reference: &Path, test: &Path) -> Result<(RgbImage, RgbImage), DiffError> {
    same_size((reference, load_png(reference)?), (test, load_png(test)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::DynamicImage;
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
        let mut bytes = b"\x89PNG\r\n\x1a\n".to_vec();
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
