use crate::alloc_prelude::*;
use crate::dynamics::RigidBodyVelocity;
use crate::math::{DVector, Jacobian, Real};

/// A temporary workspace for various updates of the multibody.
#[cfg_attr(feature = "serde-serialize", derive(Serialize, Deserialize))]
#[derive(Debug)]
pub(crate) struct MultibodyWorkspace {
    pub accs: Vec<RigidBodyVelocity<Real>>,
    pub ndofs_vec: DVector,
    /// Strider patch: each link's nonzero body-Jacobian column ranges `(start, len)`.
    /// Written by `update_mass_matrix` (and `update_acceleration`) and read by
    /// `fill_jacobians_unsolved` later in the same step; a copy (`Clone`) has none, so it
    /// takes the dense products until then, and `Multibody::clone_from` copies them.
    pub col_ranges: Vec<Vec<(usize, usize)>>,
    /// Strider patch: the same ranges, as `update_body_jacobians` computes them (kept
    /// apart: it runs before `update_mass_matrix`, and not always with it). Scratch: valid
    /// only within `update_body_jacobians`, which computes them first (forward kinematics
    /// may skip it, a copy of the workspace has none, and one taken into another's buffers
    /// has that one's).
    pub jacobian_ranges: Vec<Vec<(usize, usize)>>,
    /// Strider patch: `M J` for one link and each of the two mass matrices, reused across
    /// links and steps.
    pub mass_work: [Jacobian<Real>; 2],
    /// Strider patch: each link's nonzero body-Jacobian columns in blocks of lanes, laid
    /// out for `transposed_products_add`, reused across steps.
    pub jacobian_blocks: Vec<Vec<Real>>,
    /// Strider patch: each link's Coriolis terms over its nonzero columns, in the same
    /// layout.
    pub coriolis: Vec<Vec<Real>>,
    /// Strider patch: one link's Coriolis terms melded with its mass, in the same layout.
    pub coriolis_dt: Vec<Real>,
    /// Strider patch: what forward kinematics reads, written before it is compared with
    /// the last call's (`Multibody::kinematics_inputs_unchanged`).
    pub kinematics_inputs: Vec<u32>,
    /// Strider patch: `update_acceleration`'s position-derived forces and its copy of the
    /// generalised forces, for the energy guard; scratch.
    pub pos_forces: DVector,
    pub gen_forces: DVector,
    /// Strider patch: the energy guard's `M a` and `M v`; scratch.
    pub guard_products: [DVector; 2],
}

/// Strider patch: a copy has the workspace's sizes and none of its contents, which every
/// step writes before it reads them (the buffers are scratch). A multibody is copied
/// every few steps to take a step again (the worker's joint drives); copying the buffers,
/// about seventy allocations for a hexapod, was most of that copy's cost. (A multibody
/// copied into another's buffers, `Multibody::clone_from`, keeps that one's workspace
/// where the sizes match: stale contents, written before they are read all the same.)
impl Clone for MultibodyWorkspace {
    fn clone(&self) -> Self {
        let mut copy = Self::new();
        copy.resize(self.accs.len(), self.ndofs_vec.len());
        copy
    }
}

impl MultibodyWorkspace {
    /// Create an empty workspace.
    pub fn new() -> Self {
        MultibodyWorkspace {
            accs: Vec::new(),
            ndofs_vec: DVector::zeros(0),
            col_ranges: Vec::new(),
            jacobian_ranges: Vec::new(),
            mass_work: [Jacobian::zeros(0), Jacobian::zeros(0)],
            jacobian_blocks: Vec::new(),
            coriolis: Vec::new(),
            coriolis_dt: Vec::new(),
            kinematics_inputs: Vec::new(),
            pos_forces: DVector::zeros(0),
            gen_forces: DVector::zeros(0),
            guard_products: [DVector::zeros(0), DVector::zeros(0)],
        }
    }

    /// Strider patch: whether a copy of `other` would have this workspace's sizes (what
    /// `Clone` gives a copy; the contents are scratch).
    pub fn same_sizes(&self, other: &Self) -> bool {
        self.accs.len() == other.accs.len() && self.ndofs_vec.len() == other.ndofs_vec.len()
    }

    /// Resize the workspace so it is enough for `nlinks` links.
    pub fn resize(&mut self, nlinks: usize, ndofs: usize) {
        self.accs.resize(nlinks, RigidBodyVelocity::zero());
        self.ndofs_vec = DVector::zeros(ndofs)
    }
}
