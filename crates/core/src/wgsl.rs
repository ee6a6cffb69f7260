//! Constants a WGSL shader shares with Rust, written into the shader's source from the Rust
//! values, so that the two sides cannot disagree. A shader that uses one does not declare it.

/// The normal-incidence Fresnel reflectance of a dielectric of IOR 1.5, glTF 2.0's
/// metallic-roughness base (glTF 2.0 specification, Appendix B: F0 = 0.04): the rasterizer's
/// L_d, the CPU tracer and the GPU tracer all use it.
pub const DIELECTRIC_F0: f32 = 0.04;

/// A constant's value as WGSL types it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    U32(u32),
    I32(i32),
    F32(f32),
}

/// WGSL declarations `const NAME: TYPE = VALUE;`, one a line. Floats are written so that
/// WGSL reads back the same f32.
pub fn constants(values: &[(&str, Value)]) -> String {
    values
        .iter()
        .map(|(name, value)| match value {
            Value::U32(v) => format!("const {name}: u32 = {v}u;\n"),
            Value::I32(v) => format!("const {name}: i32 = {v};\n"),
            // Rust's Debug form of an f32 is its shortest round-tripping decimal, always
            // with a '.' or an exponent: a float literal in WGSL.
            Value::F32(v) => format!("const {name}: f32 = {v:?};\n"),
        })
        .collect()
}

/// How many times `source` declares the constant `name` (a shader given its constants from
/// Rust must declare them once, in the lines [`constants`] wrote).
pub fn declarations(source: &str, name: &str) -> usize {
    let prefix = format!("const {name}:");
    source.lines().filter(|line| line.trim_start().starts_with(&prefix)).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constants_are_declared_with_values_that_read_back_exactly() {
        let floats = [0.04f32, 1e-3, 1e-4, 3.40282e38, 1.0, 0.1 + 0.2, f32::MIN_POSITIVE];
        let named: Vec<(String, Value)> = floats.iter().enumerate().map(|(i, &v)| (format!("F{i}"), Value::F32(v))).collect();
        let refs: Vec<(&str, Value)> = named.iter().map(|(n, v)| (n.as_str(), *v)).collect();
        let source = constants(&refs);
        for (line, &v) in source.lines().zip(&floats) {
            let text = line.split(" = ").nth(1).unwrap().trim_end_matches(';');
            assert!(text.contains('.') || text.contains('e'), "{line}: not a float literal");
            assert_eq!(text.parse::<f32>().unwrap().to_bits(), v.to_bits(), "{line}");
        }
        assert_eq!(constants(&[("N", Value::U32(7)), ("M", Value::I32(-3))]), "const N: u32 = 7u;\nconst M: i32 = -3;\n");
    }
}
