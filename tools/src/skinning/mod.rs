//! Skinning without learning, below import and train: linear blend skinning and the rigid
//! predictor ([`lbs`]), dual quaternions ([`dqs`]), optimized centres of rotation ([`cor`]),
//! direct delta mush ([`direct_delta_mush`]), and the enveloping error that scores every method ([`error`]).
//! Training fits LBS weights (SSD); eval compares everything against these baselines; import
//! checks a cache against the rig's own LBS.

pub mod cor;
pub mod direct_delta_mush;
pub mod dqs;
pub mod error;
pub mod lbs;
