//! The render command's lighting flags: an environment for any scene.

use crate::error::{Error, Result};
use crate::scene::Scene;
use crate::scene::environment::{DEFAULT_SKY, EnvSource};
use clap::Args;

/// `--env`, `--env-strength`, `--env-rotation` (docs/lights.md).
#[derive(Debug, Default, Args)]
pub struct LightArgs {
    /// Light the scene with an environment: an equirectangular .exr or .hdr image, or a colour R,G,B.
    #[arg(long, value_name = "FILE|R,G,B", help_heading = "Lighting")]
    pub env: Option<String>,
    /// Scale the environment's radiance [default: the scene's, else 1].
    #[arg(
        long,
        value_name = "S",
        allow_negative_numbers = true,
        help_heading = "Lighting"
    )]
    pub env_strength: Option<f32>,
    /// Turn the environment about +Y, right-handed, in degrees [default: the scene's, else 0].
    #[arg(
        long,
        value_name = "DEG",
        allow_negative_numbers = true,
        help_heading = "Lighting"
    )]
    pub env_rotation: Option<f32>,
}

impl LightArgs {
    /// Give `scene` the environment the flags ask for ([`set`](Self::set)),
    /// and say on stderr when it is the default sky of an asset without
    /// light, or when its image had negative texels.
    pub fn apply(&self, scene: &mut Scene) -> Result<()> {
        self.set(scene)?;
        // What the user should know about the light the render will use.
        if let Some(env) = &scene.environment {
            if env.source == DEFAULT_SKY {
                eprintln!(
                    "note: {} has no light: it is lit by {DEFAULT_SKY}; give another with --env FILE|R,G,B (docs/lights.md)",
                    scene.name
                );
            }
            if env.negative_texels > 0 {
                eprintln!(
                    "warning: {}: {} texel(s) with a negative component (lossy compression's ringing) are read as 0",
                    env.source, env.negative_texels
                );
            }
        }
        Ok(())
    }

    /// `--env` replaces the scene's environment (keeping its visibility);
    /// `--env-strength` and `--env-rotation` alone change the scene's own,
    /// and are refused for a scene without one.
    fn set(&self, scene: &mut Scene) -> Result<()> {
        let source = self.env.as_deref().map(EnvSource::parse);
        let env = crate::scene::environment::overridden(
            scene.environment.as_ref(),
            source.as_ref(),
            self.env_strength,
            self.env_rotation,
        )
        .map_err(Error::Settings)?;
        if let Some(env) = env {
            scene.set_environment(env);
        }
        Ok(())
    }
}
