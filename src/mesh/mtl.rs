//! MTL material libraries: `newmtl`, `Kd`, `Ks` and `Ns`; other
//! statements are read past. A material without `Ks` or `Ns` takes 0 for
//! them, and `newmtl` starts from a diffuse 0.8 grey (MTL's defaults).
//!
//! Tolerated, with a warning: a statement with missing or unreadable
//! values, or a negative `Ns` (that field's default); `Kd r` alone
//! (g = b = r, as the format allows); a property before any `newmtl`
//! (ignored); texture maps (`map_Kd` and the like: glint has no textures).

use std::collections::HashMap;
use std::path::Path;

use glam::DVec3;

use super::report::{Report, Tolerance};
use super::text::{show, Text};
use super::MeshError;
use crate::material::Material;

pub fn read(
    src: &[u8],
    path: &Path,
    materials: &mut Vec<Material>,
    names: &mut HashMap<String, u32>,
    report: &mut Report,
) -> Result<(), MeshError> {
    let src = src.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(src);
    let mut t = Text::new(src, path);
    let mut current: Option<usize> = None;
    let mut textures_noted = false;
    while let Some(key) = t.token() {
        let key = key.to_ascii_lowercase();
        if key == b"newmtl" {
            let name = String::from_utf8_lossy(t.rest_of_line()).into_owned();
            if materials.len() >= u32::MAX as usize {
                return Err(t.error("more than 4 billion materials"));
            }
            names.insert(name, materials.len() as u32);
            materials.push(Material {
                kd: DVec3::splat(0.8),
                ks: DVec3::ZERO,
                shininess: 0.0,
            });
            current = Some(materials.len() - 1);
        } else if matches!(key.as_slice(), b"kd" | b"ks" | b"ns") {
            let name = String::from_utf8_lossy(&key).into_owned();
            let Some(m) = current.map(|i| &mut materials[i]) else {
                report.warn(
                    Tolerance::MaterialValue,
                    path,
                    t.at(),
                    format!("`{name}` before any `newmtl` is ignored"),
                );
                t.next_line();
                continue;
            };
            let values: Vec<&[u8]> = std::iter::from_fn(|| t.token_on_line()).take(4).collect();
            let parsed: Vec<Option<f64>> = values
                .iter()
                .map(|v| crate::number::parse_f64(v).filter(|x| x.is_finite()))
                .collect();
            let bad = |report: &mut Report, why: String| {
                report.warn(
                    Tolerance::MaterialValue,
                    path,
                    t.at(),
                    format!("`{name}` {why}; the default is kept"),
                );
            };
            if key == b"ns" {
                match parsed.first() {
                    None => bad(report, "has no value".into()),
                    Some(Some(v)) if *v >= 0.0 => m.shininess = *v,
                    Some(Some(v)) => bad(report, format!("is negative ({v})")),
                    Some(None) => bad(report, format!("has the value {}", show(values[0]))),
                }
            } else {
                let rgb = match parsed.as_slice() {
                    [] => Err("has no value".to_string()),
                    // `Kd r`: g and b equal r.
                    [Some(r)] => Ok(DVec3::splat(*r)),
                    [Some(r), Some(g), Some(b), ..] => Ok(DVec3::new(*r, *g, *b)),
                    _ => Err(format!(
                        "has the values {} (`spectral` and `xyz` colours are not read)",
                        values.iter().map(|v| show(v)).collect::<Vec<_>>().join(" ")
                    )),
                };
                match rgb {
                    Ok(c) if key == b"kd" => m.kd = c,
                    Ok(c) => m.ks = c,
                    Err(why) => bad(report, why),
                }
            }
        } else if (key.starts_with(b"map_") || key == b"bump" || key == b"disp") && !textures_noted
        {
            textures_noted = true;
            report.warn(
                Tolerance::TextureIgnored,
                path,
                t.at(),
                format!(
                    "texture maps (`{}`) are not rendered: glint shades with the material's \
                     colours",
                    String::from_utf8_lossy(&key)
                ),
            );
        }
        t.next_line();
    }
    Ok(())
}
