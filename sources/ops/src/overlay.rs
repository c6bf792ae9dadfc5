//! `overlay`: one colour source over another ("over" compositing), so
//! rasterized vectors sit on the imagery in the colour layer.

use relief_source::{
    ColorTile, GenerateContext, Payload, PayloadKind, Source, SourceError, SourceInfo, SourceSpec, TileKey,
};

pub const OVERLAY_KIND: &str = "overlay";
/// Bottom first, then the layer laid over it.
pub const OVERLAY_INPUTS: &[PayloadKind] = &[PayloadKind::Color, PayloadKind::Color];

#[derive(Debug)]
pub struct Overlay {
    id: String,
    inputs: Vec<String>,
    /// How opaque the top layer is laid, 0 to 1.
    opacity: f64,
}

impl Overlay {
    pub fn open(spec: &SourceSpec) -> Result<Self, SourceError> {
        spec.only_options(&["opacity"])?;
        if spec.inputs.len() != 2 {
            return Err(SourceError::option("inputs", "overlay takes two colour inputs: [bottom, top]"));
        }
        let opacity = spec.number("opacity")?.unwrap_or(1.0);
        if !(0.0..=1.0).contains(&opacity) {
            return Err(SourceError::option("opacity", format!("{opacity} is not between 0 and 1")));
        }
        Ok(Self { id: spec.id.clone(), inputs: spec.inputs.clone(), opacity })
    }
}

/// `top` over `bottom`, straight (not premultiplied) RGBA8.
pub fn over(bottom: &[u8], top: &[u8], opacity: f64) -> Vec<u8> {
    let mut out = Vec::with_capacity(bottom.len());
    for (b, t) in bottom.chunks_exact(4).zip(top.chunks_exact(4)) {
        let (ab, at) = (f64::from(b[3]) / 255.0, f64::from(t[3]) / 255.0 * opacity);
        let a = at + ab * (1.0 - at);
        for k in 0..3 {
            let c = if a > 0.0 { (f64::from(t[k]) * at + f64::from(b[k]) * ab * (1.0 - at)) / a } else { 0.0 };
            out.push(c.round().clamp(0.0, 255.0) as u8);
        }
        out.push((a * 255.0).round() as u8);
    }
    out
}

impl Source for Overlay {
    fn id(&self) -> &str {
        &self.id
    }

    fn kind(&self) -> &'static str {
        OVERLAY_KIND
    }

    fn output(&self) -> PayloadKind {
        PayloadKind::Color
    }

    fn inputs(&self) -> &[String] {
        &self.inputs
    }

    fn info(&self) -> SourceInfo {
        let mut info = SourceInfo::default();
        info.details.insert("opacity".into(), self.opacity.to_string());
        info
    }

    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError> {
        let (bottom, top) = (ctx.inputs.tile(0, key)?, ctx.inputs.tile(1, key)?);
        match (bottom.as_ref(), top.as_ref()) {
            (Payload::Color(b), Payload::Color(t)) if b.size == t.size => {
                Ok(Payload::Color(ColorTile { size: b.size, rgba: over(&b.rgba, &t.rgba, self.opacity) }))
            }
            _ => Err(SourceError::Input {
                input: self.inputs.join(", "),
                message: "overlay needs two colour tiles of one size".into(),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn over_follows_porter_duff() {
        let bottom = [0, 0, 255, 255, 10, 20, 30, 0];
        let top = [255, 0, 0, 128, 255, 255, 255, 0];
        let out = over(&bottom, &top, 1.0);
        // Half-transparent red over opaque blue: purple, opaque.
        assert_eq!(&out[..4], &[128, 0, 127, 255]);
        // Nothing over nothing stays nothing.
        assert_eq!(out[7], 0);
        // An opaque top at opacity 0 leaves the bottom as it was.
        assert_eq!(over(&bottom[..4], &[255, 0, 0, 255], 0.0), bottom[..4].to_vec());
    }
}
