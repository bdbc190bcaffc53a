//! Surface parameterizations and their distortion: the area-preserving map of a disk-type
//! surface by OMT ([`area_preserving`]), by Lie advection ([`lie_advection`]) or by the OMT
//! gradient flow ([`gradient_flow`]), the
//! area-preserving map of a closed genus-0 surface on the sphere ([`sphere_param`]; by Lie
//! advection or the gradient flow there: [`sphere_flows`]), its
//! spherical MDS map ([`spherical_mds`], Elad, Keller & Kimmel 2005), and the
//! distortion reports of any of them ([`distortion`]). The `param` command.

pub mod area_preserving;
pub mod distortion;
pub mod gradient_flow;
pub mod lie_advection;
pub mod multiresolution;
pub mod sphere_flows;
pub mod sphere_param;
pub mod spherical_mds;
