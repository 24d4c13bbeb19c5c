//! Writing results: atomically (temp file in the same folder, then rename), so an interrupted
//! run never leaves a half-written file behind.

use std::io::Write;
use std::path::Path;

use anyhow::Context;

/// Writes `bytes` to `path` atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        anyhow::bail!(
            "cannot write {}: folder {} does not exist",
            path.display(),
            dir.display()
        );
    }
    let file_name = path
        .file_name()
        .with_context(|| format!("cannot write {}: not a file path", path.display()))?;
    let tmp = dir.join(format!(
        ".{}.tmp-{}",
        file_name.to_string_lossy(),
        std::process::id()
    ));
    let result = (|| -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(err) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(err).with_context(|| format!("cannot write {}", path.display()));
    }
    Ok(())
}

/// Encodes an RGBA image as an RGB PNG (the frame is opaque) and writes it atomically.
pub fn write_png(path: &Path, image: &image::RgbaImage) -> anyhow::Result<()> {
    write_png_rgb(
        path,
        &image::DynamicImage::ImageRgba8(image.clone()).into_rgb8(),
    )
}

/// Encodes an RGB image as PNG and writes it atomically, at the encoder's fast compression: a
/// sweep writes five images a cell, and at the default level they took 0.42-0.51 s of a
/// thesis cell's comparisons against 0.32-0.40 s (the best level 4x the default's time for 7%
/// less); the files are about a third larger.
pub fn write_png_rgb(path: &Path, rgb: &image::RgbImage) -> anyhow::Result<()> {
    encode_png(path, rgb, image::codecs::png::CompressionType::Fast)
}

/// As [`write_png_rgb`], at the best compression: for the committed baselines, written once
/// and kept in the repository.
pub fn write_png_rgb_smallest(path: &Path, rgb: &image::RgbImage) -> anyhow::Result<()> {
    encode_png(path, rgb, image::codecs::png::CompressionType::Best)
}

/// Writes a linear HDR frame (premultiplied radiance, alpha = the smoke's opacity, as OpenEXR
/// expects) as an RGBA 32-bit float OpenEXR file, atomically.
pub fn write_exr(path: &Path, hdr: &smokeshadow_core::gpu::Rgba16fImage) -> anyhow::Result<()> {
    write_exr_rgba(path, hdr.width, hdr.height, &hdr.pixels)
}

/// Writes `width` x `height` RGBA pixels (row by row) as an RGBA 32-bit float OpenEXR file,
/// atomically.
pub fn write_exr_rgba(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[[f32; 4]],
) -> anyhow::Result<()> {
    let flat: Vec<f32> = pixels.iter().flatten().copied().collect();
    let image = image::Rgba32FImage::from_raw(width, height, flat)
        .context("the pixels do not fill the image")?;
    let mut bytes = std::io::Cursor::new(Vec::new());
    image::DynamicImage::ImageRgba32F(image)
        .write_to(&mut bytes, image::ImageFormat::OpenExr)
        .context("cannot encode OpenEXR")?;
    write_atomic(path, bytes.get_ref())
}

/// `path` with the extension `.exr`: the HDR file written beside a PNG.
pub fn exr_beside(path: &Path) -> std::path::PathBuf {
    path.with_extension("exr")
}

fn encode_png(
    path: &Path,
    rgb: &image::RgbImage,
    compression: image::codecs::png::CompressionType,
) -> anyhow::Result<()> {
    use image::ImageEncoder;
    use image::codecs::png::{FilterType, PngEncoder};
    let mut bytes = Vec::new();
    PngEncoder::new_with_quality(&mut bytes, compression, FilterType::Adaptive)
        .write_image(
            rgb.as_raw(),
            rgb.width(),
            rgb.height(),
            image::ExtendedColorType::Rgb8,
        )
        .context("cannot encode PNG")?;
    write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_write_replaces_and_leaves_no_temp_file() {
        let dir = std::env::temp_dir().join(format!("smokeshadow-out-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.txt");
        write_atomic(&path, b"one").unwrap();
        write_atomic(&path, b"two").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"two");
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
        let err = write_atomic(&dir.join("missing/a.txt"), b"x")
            .unwrap_err()
            .to_string();
        assert!(err.contains("does not exist"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
