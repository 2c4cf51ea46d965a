//! Host/WGSL struct layouts from one Rust definition ([`wgsl_struct!`](crate::wgsl_struct))
//! and their check against WGSL's layout rules with naga ([`check_layout`]).

/// A Rust type with a WGSL counterpart of the same size. Only types whose WGSL alignment can
/// differ from Rust's are vectors; [`check_layout`] catches a misplaced one.
pub trait WgslType {
    /// The WGSL type name.
    const WGSL: &'static str;
}

macro_rules! wgsl_types {
    ($($t:ty => $w:literal),* $(,)?) => { $(impl WgslType for $t { const WGSL: &'static str = $w; })* };
}

wgsl_types! {
    f32 => "f32", u32 => "u32", i32 => "i32",
    [f32; 2] => "vec2<f32>", [u32; 2] => "vec2<u32>", [i32; 2] => "vec2<i32>",
    [f32; 4] => "vec4<f32>", [u32; 4] => "vec4<u32>", [i32; 4] => "vec4<i32>",
    // Scalar arrays (4-byte aligned, unlike vec3/vec4): fixed-width groups inside packed
    // records, e.g. a mean or the blend channels of a splat.
    [f32; 3] => "array<f32, 3>", [f32; 8] => "array<f32, 8>",
}

/// One member of a [`WgslStruct`]: its name, WGSL type and Rust byte offset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WgslField {
    /// Member name (the same on both sides).
    pub name: &'static str,
    /// WGSL type.
    pub ty: &'static str,
    /// `offset_of!` in the Rust struct.
    pub offset: usize,
}

/// A `#[repr(C)]` Pod struct with a generated WGSL declaration (see
/// [`wgsl_struct!`](crate::wgsl_struct)).
pub trait WgslStruct: bytemuck::Pod {
    /// The struct's name in WGSL.
    const WGSL_NAME: &'static str;
    /// Its members in declaration order.
    fn wgsl_fields() -> Vec<WgslField>;
    /// `struct Name { member: type, … }` for inclusion in a kernel's source.
    fn wgsl_decl() -> String {
        let mut s = format!("struct {} {{\n", Self::WGSL_NAME);
        for f in Self::wgsl_fields() {
            s.push_str(&format!("    {}: {},\n", f.name, f.ty));
        }
        s.push_str("}\n");
        s
    }
}

/// Declares a `#[repr(C)]` Pod struct (fields public) and implements [`WgslStruct`] for it,
/// so that the WGSL declaration is generated from this one definition. Field types must
/// implement [`WgslType`]; the calling crate must depend on `bytemuck` (for the derives).
///
/// ```
/// gs_gpu::wgsl_struct! {
///     /// Frame constants of some kernel.
///     pub struct Frame as "Frame" {
///         /// Image size.
///         size: [u32; 2],
///         scale: f32,
///         pad: u32,
///     }
/// }
/// use gs_gpu::WgslStruct;
/// assert!(Frame::wgsl_decl().contains("size: vec2<u32>,"));
/// ```
#[macro_export]
macro_rules! wgsl_struct {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident as $wgsl:literal {
            $( $(#[$fmeta:meta])* $field:ident : $ty:ty ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[repr(C)]
        #[derive(Debug, Clone, Copy, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
        $vis struct $name {
            $( $(#[$fmeta])* pub $field: $ty, )*
        }
        // A struct is also a member type of other structs (nested records).
        impl $crate::WgslType for $name {
            const WGSL: &'static str = $wgsl;
        }
        impl $crate::WgslStruct for $name {
            const WGSL_NAME: &'static str = $wgsl;
            fn wgsl_fields() -> ::std::vec::Vec<$crate::WgslField> {
                ::std::vec![$($crate::WgslField {
                    name: stringify!($field),
                    ty: <$ty as $crate::WgslType>::WGSL,
                    offset: ::std::mem::offset_of!($name, $field),
                }),*]
            }
        }
    };
}

/// One struct whose WGSL a kernel takes from its Rust definition: its declaration, and the
/// check of a compiled source's layout of it against the Rust struct. A kernel keeps one list
/// of these for both its declarations ([`declarations`]) and its layout test, so that no
/// declared struct goes unchecked.
#[derive(Clone, Copy)]
pub struct GeneratedStruct {
    /// The WGSL declaration.
    pub decl: fn() -> String,
    /// [`check_layout`] of the struct.
    pub check: fn(&str) -> Result<(), String>,
}

impl GeneratedStruct {
    /// The entry of `T`.
    pub fn of<T: WgslStruct>() -> Self {
        Self { decl: T::wgsl_decl, check: check_layout::<T> }
    }
}

/// The WGSL declarations of `structs`, in order (the start of a kernel's source).
pub fn declarations(structs: &[GeneratedStruct]) -> String {
    structs.iter().map(|g| (g.decl)()).collect()
}

/// [`check_layout`] of each of `structs` against the whole kernel source `src`: the layout test
/// of a crate whose kernels declare `structs`.
pub fn check_layouts(structs: &[GeneratedStruct], src: &str) -> Result<(), String> {
    structs.iter().try_for_each(|g| (g.check)(src))
}

/// Bytes of `count` records of `T`: buffer sizes and binding offsets come from the record types,
/// never from strides written by hand.
pub const fn bytes_of<T>(count: usize) -> u64 {
    (count * std::mem::size_of::<T>()) as u64
}

/// Parses and validates a whole kernel source with naga, as the device's shader compiler
/// would: type errors that parsing alone lets through (a constructor of the wrong type, a
/// binding used as another type) fail here, in a test that needs no adapter.
pub fn validate_kernel(source: &str) -> Result<(), String> {
    use wgpu::naga;
    let module = naga::front::wgsl::parse_str(source).map_err(|e| e.emit_to_string(source))?;
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
        .validate(&module)
        .map(|_| ())
        .map_err(|e| e.emit_to_string(source))
}

/// Checks the WGSL struct `T::WGSL_NAME` in `source` (a whole module, e.g. a composed kernel
/// source) against the Rust struct `T`: the same member names in the same order, each at the
/// Rust offset, and the same size. Any struct written or edited by hand on one side only
/// fails here.
pub fn check_layout<T: WgslStruct>(source: &str) -> Result<(), String> {
    use wgpu::naga;
    let module = naga::front::wgsl::parse_str(source).map_err(|e| e.emit_to_string(source))?;
    let mut layouter = naga::proc::Layouter::default();
    layouter
        .update(module.to_ctx())
        .map_err(|e| format!("layout: {e}"))?;
    let name = T::WGSL_NAME;
    let (handle, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .ok_or_else(|| format!("struct {name} not found in the WGSL"))?;
    let naga::TypeInner::Struct { members, span } = &ty.inner else {
        return Err(format!("{name} is not a struct in the WGSL"));
    };
    let wgsl: Vec<(String, usize)> = members
        .iter()
        .map(|m| (m.name.clone().unwrap_or_default(), m.offset as usize))
        .collect();
    let rust: Vec<(String, usize)> = T::wgsl_fields()
        .iter()
        .map(|f| (f.name.to_string(), f.offset))
        .collect();
    if wgsl != rust {
        return Err(format!(
            "{name}: WGSL members (name, offset) {wgsl:?} != Rust {rust:?}"
        ));
    }
    let size = std::mem::size_of::<T>();
    if *span as usize != size || layouter[handle].size as usize != size {
        return Err(format!("{name}: WGSL size {span} != Rust size {size}"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    crate::wgsl_struct! {
        /// A test struct.
        struct Probe as "Probe" {
            a: [f32; 4],
            b: u32,
            d: f32,
            c: [u32; 2],
        }
    }

    #[test]
    fn generated_declaration_matches_the_rust_layout() {
        let src = Probe::wgsl_decl();
        assert!(src.contains("c: vec2<u32>,"), "{src}");
        check_layout::<Probe>(&src).unwrap();
    }

    #[test]
    fn a_field_on_one_side_only_or_a_misaligned_one_fails() {
        let ok = "struct Probe { a: vec4<f32>, b: u32, d: f32, c: vec2<u32> }";
        check_layout::<Probe>(ok).unwrap();
        let extra = "struct Probe { a: vec4<f32>, b: u32, d: f32, c: vec2<u32>, e: u32 }";
        assert!(
            check_layout::<Probe>(extra)
                .unwrap_err()
                .contains("members")
        );
        let missing = "struct Probe { a: vec4<f32>, b: u32, d: f32 }";
        assert!(check_layout::<Probe>(missing).is_err());
        // Same names and order, WGSL alignment moves a member: vec3 packs `b` at 12, and a
        // vec2 after one u32 starts at 8, not 4.
        let vec3 = "struct Probe { a: vec3<f32>, b: u32, d: f32, c: vec2<u32> }";
        assert!(check_layout::<Probe>(vec3).is_err());
        let swapped = "struct Probe { a: vec4<f32>, b: u32, c: vec2<u32>, d: f32 }";
        assert!(check_layout::<Probe>(swapped).is_err());
        assert!(check_layout::<Probe>("struct Other { x: u32 }").is_err());
    }
}
