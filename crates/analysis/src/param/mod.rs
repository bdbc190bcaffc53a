//! Surface parameterizations and their distortion: the area-preserving map of a disk-type
//! surface by OMT ([`area_preserving`]) or by Lie advection ([`lie_advection`]), the
//! area-preserving map of a closed genus-0 surface on the sphere ([`sphere_param`]), and the
//! distortion reports of any of them ([`distortion`]). The `param` command.

pub mod area_preserving;
pub mod distortion;
pub mod lie_advection;
pub mod sphere_param;
