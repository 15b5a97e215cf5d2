use crate::alloc_prelude::*;
use crate::dynamics::RigidBodyVelocity;
use crate::math::{DVector, Jacobian, Real};

/// A temporary workspace for various updates of the multibody.
#[cfg_attr(feature = "serde-serialize", derive(Serialize, Deserialize))]
#[derive(Clone, Debug)]
pub(crate) struct MultibodyWorkspace {
    pub accs: Vec<RigidBodyVelocity<Real>>,
    pub ndofs_vec: DVector,
    /// Strider patch: each link's nonzero body-Jacobian column ranges `(start, len)`.
    pub col_ranges: Vec<Vec<(usize, usize)>>,
    /// Strider patch: the same ranges, as `update_body_jacobians` computes them (kept
    /// apart: it runs before `update_mass_matrix`, and not always with it).
    pub jacobian_ranges: Vec<Vec<(usize, usize)>>,
    /// Strider patch: `M J` for one link, reused across links and steps.
    pub mass_work: Jacobian<Real>,
    /// Strider patch: one link's nonzero body-Jacobian columns laid out for
    /// `transposed_product_add`, reused across links and steps.
    pub jacobian_rows: Vec<Real>,
}

impl MultibodyWorkspace {
    /// Create an empty workspace.
    pub fn new() -> Self {
        MultibodyWorkspace {
            accs: Vec::new(),
            ndofs_vec: DVector::zeros(0),
            col_ranges: Vec::new(),
            jacobian_ranges: Vec::new(),
            mass_work: Jacobian::zeros(0),
            jacobian_rows: Vec::new(),
        }
    }

    /// Resize the workspace so it is enough for `nlinks` links.
    pub fn resize(&mut self, nlinks: usize, ndofs: usize) {
        self.accs.resize(nlinks, RigidBodyVelocity::zero());
        self.ndofs_vec = DVector::zeros(ndofs)
    }
}
