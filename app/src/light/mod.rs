//! Light from the environment (scene set-up layer, pure CPU): direction samples from any source
//! ([`samples`]), the sun found in them ([`sun_finder`]; a clipped one centred on the aureole
//! around it, [`aureole`]), the rest of the sky as nine-coefficient
//! SH irradiance ([`sh9`]), and the default sunlight, daylight and shadow strength measured from
//! them ([`measure`]), restoring a clipped sun from the ground's colours ([`ground_split`]) where
//! they show it, else with a clear-sky model ([`clear_sky`]) whose turbidity is read from the
//! sky's shape ([`sky_model`]).

pub mod aureole;
pub mod clear_sky;
pub mod ggx;
pub mod ground_split;
pub mod measure;
pub mod samples;
pub mod sh9;
pub mod sky_model;
pub mod sun_finder;
