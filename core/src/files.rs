//! Where the files a scene names come from: the particle file or sequence of `[particles]`, the
//! OpenVDB file or sequence of `[volume]`, a scene file's own text. The core never opens a path
//! itself; it asks a scene's [`Files`] for the bytes, so the same scene reads from the disk in
//! the CLI and from the files dropped on the web page.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A source of file bytes by path.
pub trait FileSource: Send + Sync {
    /// The bytes of `path`, or why not (`NotFound` for a file the source does not hold).
    fn read(&self, path: &Path) -> std::io::Result<Vec<u8>>;
}

/// A shared [`FileSource`]. Its default is the host's file system where there is one (not on
/// `wasm32-unknown-unknown`, where it holds no files).
#[derive(Clone)]
pub struct Files(Arc<dyn FileSource>);

impl Files {
    /// Files from any source.
    pub fn new(source: impl FileSource + 'static) -> Self {
        Self(Arc::new(source))
    }

    /// The host's file system (one shared handle: every scene read from it compares equal).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn host() -> Self {
        static HOST: std::sync::OnceLock<Files> = std::sync::OnceLock::new();
        HOST.get_or_init(|| Self::new(HostFiles)).clone()
    }

    /// Files held in memory, by path (the web page's dropped files).
    pub fn memory(files: impl IntoIterator<Item = (PathBuf, Vec<u8>)>) -> Self {
        Self::new(MemoryFiles(files.into_iter().collect()))
    }

    /// The bytes of `path`.
    pub fn read(&self, path: &Path) -> std::io::Result<Vec<u8>> {
        self.0.read(path)
    }

    /// The UTF-8 text of `path`.
    pub fn read_to_string(&self, path: &Path) -> std::io::Result<String> {
        String::from_utf8(self.read(path)?).map_err(|_| {
            std::io::Error::new(std::io::ErrorKind::InvalidData, "it is not UTF-8 text")
        })
    }
}

impl Default for Files {
    fn default() -> Self {
        #[cfg(not(target_arch = "wasm32"))]
        return Self::host();
        #[cfg(target_arch = "wasm32")]
        Self::memory([])
    }
}

/// Two handles are equal when they share one source.
impl PartialEq for Files {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl fmt::Debug for Files {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Files")
    }
}

/// The host's file system.
#[cfg(not(target_arch = "wasm32"))]
struct HostFiles;

#[cfg(not(target_arch = "wasm32"))]
impl FileSource for HostFiles {
    fn read(&self, path: &Path) -> std::io::Result<Vec<u8>> {
        std::fs::read(path)
    }
}

/// Files in memory, by path.
struct MemoryFiles(BTreeMap<PathBuf, Vec<u8>>);

impl FileSource for MemoryFiles {
    fn read(&self, path: &Path) -> std::io::Result<Vec<u8>> {
        self.0.get(path).cloned().ok_or_else(|| {
            std::io::Error::new(std::io::ErrorKind::NotFound, "no such file was given")
        })
    }
}

/// A folder of a [`Files`]: where a scene's relative file names are looked up (the scene file's
/// folder; empty for a bare file's scene, whose names are whole paths).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Folder {
    pub dir: PathBuf,
    pub files: Files,
}

impl Folder {
    /// `dir` of `files`.
    pub fn new(dir: impl Into<PathBuf>, files: Files) -> Self {
        Self {
            dir: dir.into(),
            files,
        }
    }

    /// `name`'s path in the folder.
    pub fn join(&self, name: impl AsRef<Path>) -> PathBuf {
        self.dir.join(name)
    }

    /// The bytes of `name` in the folder.
    pub fn read(&self, name: impl AsRef<Path>) -> std::io::Result<Vec<u8>> {
        self.files.read(&self.join(name))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_files_hold_what_they_were_given_and_nothing_else() {
        let files = Files::memory([(PathBuf::from("drop/a.ply"), b"ply".to_vec())]);
        let folder = Folder::new("drop", files.clone());
        assert_eq!(folder.read("a.ply").unwrap(), b"ply");
        let missing = folder.read("b.ply").unwrap_err();
        assert_eq!(missing.kind(), std::io::ErrorKind::NotFound);
        assert_eq!(folder, Folder::new("drop", files));
        assert_ne!(folder, Folder::new("drop", Files::memory([])));
    }

    #[cfg(not(target_arch = "wasm32"))]
    #[test]
    fn every_handle_of_the_host_is_one_source() {
        assert_eq!(Files::host(), Files::default());
        assert_eq!(Folder::default(), Folder::new("", Files::host()));
    }
}
