//! What a Rust mirror of a WGSL struct claims about its layout, so a test can hold it against
//! naga's reflection of the WGSL struct: the size, and the offset of every named field (fields
//! whose names start with `_` are padding and only count towards the size).
//!
//! Each module that owns a mirror lists it with [`mirror_layout!`] in a `layouts()` function;
//! the test in `shadow::tests` gathers them all.

/// A Rust struct's layout and the WGSL struct it mirrors.
#[derive(Clone, Debug)]
pub struct MirrorLayout {
    pub rust: &'static str,
    /// The shader file (under `shaders/`) that declares the WGSL struct.
    pub wgsl_file: &'static str,
    pub wgsl_struct: &'static str,
    pub size: usize,
    /// (field, byte offset) of every named field.
    pub fields: Vec<(&'static str, usize)>,
}

/// `mirror_layout!(RustType, "file.wgsl", "WgslStruct", [field, ...])`.
#[macro_export]
macro_rules! mirror_layout {
    ($ty:ty, $file:expr, $name:expr, [$($field:ident),* $(,)?]) => {
        $crate::gpu::MirrorLayout {
            rust: stringify!($ty),
            wgsl_file: $file,
            wgsl_struct: $name,
            size: ::std::mem::size_of::<$ty>(),
            fields: vec![$((stringify!($field), ::std::mem::offset_of!($ty, $field))),*],
        }
    };
}
