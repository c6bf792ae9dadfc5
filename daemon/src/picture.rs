//! The picture a manifest asks for: the declared effects' options, the
//! renderer's `[quality]` knobs, the camera and the sun, parsed from what
//! the manifest holds as written (`Manifest::picture`) and checked. A scene
//! is loaded (and its manifest read again) with `check`, so a manifest
//! whose picture is wrong is refused like any other error in it, naming
//! the field; `Picture::of` hands the parsed picture to what draws it.

use std::sync::{Arc, Mutex, Weak};

use relief_renderer::{ClipmapConfig, InstanceBands};

use crate::effects::EffectSettings;
use crate::manifest::{Manifest, ManifestError, RawCamera, SUNLIT};
use crate::sun::Sun;

/// Default of `[quality] interactive_scale`: half of each side (a quarter of
/// the pixels) while the user drags.
pub const DEFAULT_INTERACTIVE_SCALE: f64 = 0.5;

/// Default of `[quality] frame_jpeg_quality`: the JPEG quality of frames
/// sent while the camera moves (`make accuracy` shows its error against
/// bytes and encode time).
pub const DEFAULT_FRAME_JPEG_QUALITY: u8 = 80;

/// Default of `[quality] terrain_mesh_error_m`: the quantized-mesh
/// terrain's largest vertical error at its finest level, metres (`make
/// accuracy` shows its error against time and bytes per tile).
pub const DEFAULT_TERRAIN_MESH_ERROR_M: f64 = 1.0;

/// Checks a JPEG quality knob: 1 to 100.
pub fn jpeg_quality(q: u32) -> Result<u8, String> {
    u8::try_from(q).ok().filter(|q| (1..=100).contains(q)).ok_or_else(|| format!("{q} is not from 1 to 100"))
}

/// The picture a manifest asks for, parsed and checked.
#[derive(Debug, Clone, PartialEq)]
pub struct Picture {
    /// The declared effects' options.
    pub effect_settings: EffectSettings,
    /// The renderer's accuracy knobs: samples per clipmap level side and
    /// how many levels.
    pub clipmap: ClipmapConfig,
    /// The fraction of each side a view is rendered at while its user
    /// drags (full size again once the camera rests).
    pub interactive_scale: f64,
    /// The JPEG quality of frames sent while a view is interactive.
    pub frame_jpeg_quality: u8,
    /// The instances layer's distance bands and where models give way to
    /// billboards.
    pub bands: InstanceBands,
    /// The quantized-mesh terrain's largest vertical error at its finest
    /// level, metres; each coarser level allows twice its child's.
    pub terrain_mesh_error_m: f64,
    pub camera: RawCamera,
    /// Where the sun is (`[sun]`): what lighting follows.
    pub sun: Sun,
}

/// Checks the picture `manifest` asks for: the check a scene is loaded with.
pub fn check(manifest: &Manifest) -> Result<(), ManifestError> {
    Picture::parse(manifest).map(drop)
}

impl Picture {
    /// Parses and checks the picture `manifest` holds; errors name the
    /// manifest and the field.
    pub fn parse(manifest: &Manifest) -> Result<Self, ManifestError> {
        let section = &manifest.picture;
        let knobs = &section.knobs;
        let field = |field: &str, message: String| ManifestError::Field {
            path: manifest.path.clone(),
            field: field.into(),
            message,
        };
        let mut effect_settings = EffectSettings::default();
        for (name, params) in &section.effects {
            effect_settings
                .add(name, params)
                .map_err(|(option, message)| field(&format!("effects.{name}.{option}"), message))?;
        }
        for (name, value) in [
            ("atmosphere_steps", knobs.atmosphere_steps),
            ("atmosphere_downsample", knobs.atmosphere_downsample),
            ("shadow_cascades", knobs.shadow_cascades),
            ("shadow_map_size", knobs.shadow_map_size),
            ("detail_octaves", knobs.detail_octaves),
        ] {
            let Some(value) = value else { continue };
            effect_settings
                .set_quality(name, value)
                .map_err(|(knob, message)| field(&format!("quality.{knob}"), message))?;
        }
        let defaults = ClipmapConfig::default();
        let clipmap = ClipmapConfig {
            n: knobs.clipmap_grid_size.unwrap_or(defaults.n),
            levels: knobs.clipmap_levels.unwrap_or(defaults.levels),
            color_detail: knobs.color_detail.unwrap_or(defaults.color_detail),
        };
        let knob = if [1, 2, 4].contains(&clipmap.color_detail) { "clipmap_grid_size" } else { "color_detail" };
        clipmap.validate().map_err(|e| field(&format!("quality.{knob}"), e))?;
        let three = |name: &str, values: &Option<Vec<f64>>| -> Result<Option<[f64; 3]>, ManifestError> {
            match values.as_deref() {
                None => Ok(None),
                Some(&[a, b, c]) => Ok(Some([a, b, c])),
                Some(v) => {
                    Err(field(&format!("quality.{name}"), format!("{} values: give one per band (three)", v.len())))
                }
            }
        };
        let defaults = InstanceBands::default();
        let bands = InstanceBands {
            edges_m: three("instance_bands_m", &knobs.instance_bands_m)?.unwrap_or(defaults.edges_m),
            densities: three("instance_band_densities", &knobs.instance_band_densities)?.unwrap_or(defaults.densities),
            model_distance_m: knobs.instance_model_distance_m.unwrap_or(defaults.model_distance_m),
        };
        bands.validate().map_err(|(name, message)| field(&format!("quality.{name}"), message))?;
        let interactive_scale = knobs.interactive_scale.unwrap_or(DEFAULT_INTERACTIVE_SCALE);
        if !(interactive_scale.is_finite() && (0.1..=1.0).contains(&interactive_scale)) {
            return Err(field("quality.interactive_scale", format!("{interactive_scale} is not from 0.1 to 1")));
        }
        let frame_jpeg_quality = knobs
            .frame_jpeg_quality
            .map_or(Ok(DEFAULT_FRAME_JPEG_QUALITY), jpeg_quality)
            .map_err(|message| field("quality.frame_jpeg_quality", message))?;
        let terrain_mesh_error_m = knobs.terrain_mesh_error_m.unwrap_or(DEFAULT_TERRAIN_MESH_ERROR_M);
        if !(terrain_mesh_error_m.is_finite() && (0.0..=1000.0).contains(&terrain_mesh_error_m)) {
            return Err(field(
                "quality.terrain_mesh_error_m",
                format!("{terrain_mesh_error_m} is not from 0 to 1000 m"),
            ));
        }
        let raw_sun = &section.sun;
        let time = match &raw_sun.time {
            None => None,
            Some(toml::Value::String(t)) => Some(t.clone()),
            Some(toml::Value::Datetime(t)) => Some(t.to_string()),
            Some(other) => return Err(field("sun.time", format!("{other} is not a date-time"))),
        };
        let sun = Sun::parse(time.as_deref(), raw_sun.azimuth_deg, raw_sun.elevation_deg)
            .map_err(|(name, message)| field(&format!("sun.{name}"), message))?;
        let sunlit = manifest.effects.iter().any(|e| SUNLIT.contains(&e.as_str()));
        if (time.is_some() || raw_sun.azimuth_deg.is_some() || raw_sun.elevation_deg.is_some()) && !sunlit {
            return Err(field(
                "sun",
                format!("no declared effect follows the sun (declare one of {})", SUNLIT.join(", ")),
            ));
        }
        Ok(Self {
            effect_settings,
            clipmap,
            interactive_scale,
            frame_jpeg_quality,
            bands,
            terrain_mesh_error_m,
            camera: section.camera,
            sun,
        })
    }

    /// The picture of a served manifest, parsed once per manifest (the
    /// last few are kept). A served manifest passed `check`; should one
    /// not have, its error is logged and the defaults drawn.
    pub fn of(manifest: &Arc<Manifest>) -> Arc<Self> {
        static KEPT: Mutex<Vec<(Weak<Manifest>, Arc<Picture>)>> = Mutex::new(Vec::new());
        let mut kept = KEPT.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some((_, picture)) = kept.iter().find(|(m, _)| std::ptr::eq(m.as_ptr(), Arc::as_ptr(manifest))) {
            return Arc::clone(picture);
        }
        let picture = Arc::new(Self::parse(manifest).unwrap_or_else(|e| {
            tracing::error!("{e}; drawing the defaults");
            Self::default_for(manifest)
        }));
        kept.retain(|(m, _)| m.strong_count() > 0);
        if kept.len() >= 8 {
            kept.remove(0);
        }
        kept.push((Arc::downgrade(manifest), Arc::clone(&picture)));
        picture
    }

    fn default_for(manifest: &Manifest) -> Self {
        Self {
            effect_settings: EffectSettings::default(),
            clipmap: ClipmapConfig::default(),
            interactive_scale: DEFAULT_INTERACTIVE_SCALE,
            frame_jpeg_quality: DEFAULT_FRAME_JPEG_QUALITY,
            bands: InstanceBands::default(),
            terrain_mesh_error_m: DEFAULT_TERRAIN_MESH_ERROR_M,
            camera: manifest.picture.camera,
            sun: Sun::default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn picture(text: &str) -> Result<Picture, ManifestError> {
        Picture::parse(&Manifest::parse(text, Path::new("/scenes/alps/scene.toml"))?)
    }

    #[test]
    fn fog_takes_its_options_in_range_and_nothing_else() {
        let scene = |fog: &str| {
            picture(&format!(
                "[scene]\nname='a'\n[[source]]\nid='d'\nkind='gdal'\npath='d.tif'\n[layers]\nheight='d'\n[effects]\nfog = {fog}\n"
            ))
        };
        assert_eq!(scene("{}").unwrap().effect_settings.fog, Some(relief_renderer::Fog::DEFAULT));
        let fog = scene("{ density = 0.001, falloff_m = 300, base_m = 200, color = '#ff8000' }")
            .unwrap()
            .effect_settings
            .fog
            .unwrap();
        assert_eq!((fog.density_per_m, fog.falloff_m, fog.base_m), (0.001, 300.0, 200.0));
        assert_eq!(fog.color, [1.0, 128.0 / 255.0, 0.0]);
        for (bad, message) in [
            ("{ density = -1 }", "effects.fog.density"),
            ("{ density = 'thick' }", "effects.fog.density"),
            ("{ falloff_m = 0 }", "effects.fog.falloff_m"),
            ("{ color = 'grey' }", "effects.fog.color"),
            ("{ visibility_m = 500 }", "effects.fog.visibility_m"),
        ] {
            let e = scene(bad).unwrap_err().to_string();
            assert!(e.contains(message), "{bad}: {e}");
        }
        assert!(picture("[scene]\nname='a'\n").unwrap().effect_settings.fog.is_none());
    }

    #[test]
    fn errors_name_the_field() {
        let cases = [
            // An effect's option it would ignore is refused too.
            (
                "[scene]\nname='a'\n[[source]]\nid='t'\nkind='gdal'\npath='t.tif'\n[layers]\nheight='t'\n[effects]\nlighting={ sun = 'noon' }\n",
                "field 'effects.lighting.sun'",
            ),
            ("[scene]\nname='a'\n[sun]\ntime = 2026-06-21T15:00:00\n", "field 'sun.time'"),
            ("[scene]\nname='a'\n[sun]\nazimuth_deg = 180\nelevation_deg = 30\n", "no declared effect follows the sun"),
            ("[scene]\nname='a'\n[quality]\ninteractive_scale = 2\n", "field 'quality.interactive_scale'"),
            ("[scene]\nname='a'\n[quality]\nframe_jpeg_quality = 0\n", "field 'quality.frame_jpeg_quality'"),
            ("[scene]\nname='a'\n[quality]\ninstance_bands_m = [1, 2]\n", "field 'quality.instance_bands_m'"),
        ];
        for (text, expected) in cases {
            let msg = picture(text).unwrap_err().to_string();
            assert!(msg.contains(expected), "{msg:?} should contain {expected:?}");
            assert!(msg.ends_with("/scenes/alps/scene.toml"), "{msg}");
        }
    }

    #[test]
    fn a_served_manifest_is_parsed_once() {
        let manifest = Arc::new(Manifest::parse("[scene]\nname='a'\n", Path::new("/s/scene.toml")).unwrap());
        assert!(Arc::ptr_eq(&Picture::of(&manifest), &Picture::of(&manifest)));
        let other = Arc::new((*manifest).clone());
        assert!(!Arc::ptr_eq(&Picture::of(&manifest), &Picture::of(&other)));
    }
}
