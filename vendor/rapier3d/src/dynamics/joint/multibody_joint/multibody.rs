use super::mass_factor::{self, MassFactor};
use super::multibody_link::{MultibodyLink, MultibodyLinkVec};
use super::multibody_workspace::MultibodyWorkspace;
use crate::alloc_prelude::*;
use crate::dynamics::integration_parameters::SpringCoefficients;
use crate::dynamics::solver::{GenericJointConstraint, WritebackId};
use crate::dynamics::{
    IntegrationParameters, RigidBodyHandle, RigidBodySet, RigidBodyType, RigidBodyVelocity,
};
use crate::math::{
    ANG_DIM, AngVector, DIM, DVector, Jacobian, Pose, Real, SPATIAL_DIM, SimdAngVector, Vector,
};
#[cfg(test)]
use crate::math::{AngDim, Dim};
use crate::prelude::MultibodyJoint;
#[cfg(feature = "dim3")]
use crate::utils::mat_to_na;
use crate::utils::{AngularInertiaOps, CrossProduct, CrossProductMatrix, IndexMut2, vect_to_na};
#[cfg(test)]
use na::OMatrix;
use na::{self, DMatrix, DVectorView, DVectorViewMut, Dyn, SMatrix, SVector, StorageMut};

#[cfg(doc)]
use crate::prelude::{GenericJoint, RigidBody};

#[repr(C)]
#[derive(Copy, Clone, Debug, Default)]
struct Force {
    linear: Vector,
    angular: AngVector,
}

impl Force {
    fn new(linear: Vector, angular: AngVector) -> Self {
        Self { linear, angular }
    }

    fn as_vector(&self) -> &SVector<Real, SPATIAL_DIM> {
        unsafe { core::mem::transmute(self) }
    }
}

#[cfg(feature = "dim2")]
fn concat_rb_mass_matrix(mass: Vector, inertia: Real) -> SMatrix<Real, SPATIAL_DIM, SPATIAL_DIM> {
    let mut result = SMatrix::<Real, SPATIAL_DIM, SPATIAL_DIM>::zeros();
    result[(0, 0)] = mass.x;
    result[(1, 1)] = mass.y;
    result[(2, 2)] = inertia;
    result
}

#[cfg(feature = "dim3")]
fn concat_rb_mass_matrix(
    mass: Vector,
    inertia: na::Matrix3<Real>,
) -> SMatrix<Real, SPATIAL_DIM, SPATIAL_DIM> {
    let mut result = SMatrix::<Real, SPATIAL_DIM, SPATIAL_DIM>::zeros();
    result[(0, 0)] = mass.x;
    result[(1, 1)] = mass.y;
    result[(2, 2)] = mass.z;
    result
        .fixed_view_mut::<ANG_DIM, ANG_DIM>(DIM, DIM)
        .copy_from(&inertia);
    result
}

/// A holonomic coupling between two generalized coordinates of a single
/// [`Multibody`], `q2 = coeff · q1 + offset`, enforced as a velocity-level
/// equality constraint. This is how MuJoCo's `<equality><joint>` (a polynomial
/// joint-to-joint coupling) is represented for the linear (first-order) case —
/// e.g. the robotiq gripper's two driver joints moving together.
#[cfg_attr(feature = "serde-serialize", derive(Serialize, Deserialize))]
#[derive(Copy, Clone, Debug)]
pub struct MultibodyDofCoupling {
    /// Internal id of the link owning the first joint.
    pub link1: usize,
    /// Local free-DoF index of the coupled DoF within `link1` (its position in
    /// that link's slice of the generalized vectors).
    pub dof1: usize,
    /// Spatial-coordinate axis (`0..6`) of `link1`'s coupled DoF, used to read
    /// its generalized position from the joint coords.
    pub axis1: usize,
    /// Internal id of the link owning the second joint.
    pub link2: usize,
    /// Local free-DoF index of the coupled DoF within `link2`.
    pub dof2: usize,
    /// Spatial-coordinate axis (`0..6`) of `link2`'s coupled DoF.
    pub axis2: usize,
    /// Linear coupling coefficient: the constraint is `q2 − coeff·q1 − offset = 0`.
    pub coeff: Real,
    /// Constant offset of the coupling.
    pub offset: Real,
}

/// An articulated body simulated using the reduced-coordinates approach.
#[cfg_attr(feature = "serde-serialize", derive(Serialize, Deserialize))]
#[derive(Debug)]
pub struct Multibody {
    // TODO: serialization: skip the workspace fields.
    pub(crate) links: MultibodyLinkVec,
    pub(crate) velocities: DVector,
    pub(crate) damping: DVector,
    /// Per-DoF reflected rotor inertia (matches MuJoCo’s concept of `armature`).
    pub(crate) armature: DVector,
    /// Per-DoF dry joint friction (matches MuJoCo’s `frictionloss`).
    pub(crate) frictions: DVector,
    pub(crate) accelerations: DVector,

    body_jacobians: Vec<Jacobian<Real>>,
    // NOTE: the mass matrices are dimensioned based on the non-kinematic degrees of
    //       freedoms only. The `Self::augmented_mass_permutation` sequence can be used to
    //       move dofs from/to a format that matches the augmented mass.
    // TODO: use sparse matrices?
    augmented_mass: DMatrix<Real>,
    inv_augmented_mass: MassFactor,
    // The indexing sequence for moving all kinematics degrees of
    // freedoms to the end of the generalized coordinates vector.
    augmented_mass_indices: IndexSequence,

    acc_augmented_mass: DMatrix<Real>,
    acc_inv_augmented_mass: MassFactor,

    ndofs: usize,
    pub(crate) root_is_dynamic: bool,
    pub(crate) solver_id: u32,
    self_contacts_enabled: bool,
    /// Holonomic couplings between two of this multibody's generalized
    /// coordinates (`q2 = coeff·q1 + offset`), e.g. MuJoCo's
    /// `<equality><joint>`. Resolved as velocity constraints each step.
    couplings: Vec<MultibodyDofCoupling>,
    /// Strider patch: the bits the last [`Self::forward_kinematics`] read
    /// ([`Self::kinematics_inputs_unchanged`]), stored once it has computed from them; a
    /// call that finds them unchanged leaves the poses and Jacobians it computed, the same
    /// bits.
    kinematics_inputs: Vec<u32>,

    /*
     * Workspaces.
     */
    workspace: MultibodyWorkspace,
}
impl Default for Multibody {
    fn default() -> Self {
        Multibody::new()
    }
}

/// Strider patch: `clone_from` copies into the multibody's own buffers where their sizes
/// match (the worker copies the world every few steps and puts it back to take a step
/// again: about forty allocations a copy for a hexapod, most of them the body Jacobians),
/// so it leaves what `clone` would, without allocating. The fields are named in full
/// below, so a field added upstream fails to compile here rather than go uncopied.
impl Clone for Multibody {
    fn clone(&self) -> Self {
        let Multibody {
            links,
            velocities,
            damping,
            armature,
            frictions,
            accelerations,
            body_jacobians,
            augmented_mass,
            inv_augmented_mass,
            augmented_mass_indices,
            acc_augmented_mass,
            acc_inv_augmented_mass,
            ndofs,
            root_is_dynamic,
            solver_id,
            self_contacts_enabled,
            couplings,
            kinematics_inputs,
            workspace,
        } = self;
        Multibody {
            links: links.clone(),
            velocities: velocities.clone(),
            damping: damping.clone(),
            armature: armature.clone(),
            frictions: frictions.clone(),
            accelerations: accelerations.clone(),
            body_jacobians: body_jacobians.clone(),
            augmented_mass: augmented_mass.clone(),
            inv_augmented_mass: inv_augmented_mass.clone(),
            augmented_mass_indices: augmented_mass_indices.clone(),
            acc_augmented_mass: acc_augmented_mass.clone(),
            acc_inv_augmented_mass: acc_inv_augmented_mass.clone(),
            ndofs: *ndofs,
            root_is_dynamic: *root_is_dynamic,
            solver_id: *solver_id,
            self_contacts_enabled: *self_contacts_enabled,
            couplings: couplings.clone(),
            kinematics_inputs: kinematics_inputs.clone(),
            workspace: workspace.clone(),
        }
    }

    fn clone_from(&mut self, source: &Self) {
        let Multibody {
            links,
            velocities,
            damping,
            armature,
            frictions,
            accelerations,
            body_jacobians,
            augmented_mass,
            inv_augmented_mass,
            augmented_mass_indices,
            acc_augmented_mass,
            acc_inv_augmented_mass,
            ndofs,
            root_is_dynamic,
            solver_id,
            self_contacts_enabled,
            couplings,
            kinematics_inputs,
            workspace,
        } = source;
        self.links.0.clone_from(&links.0);
        copy_matrix(&mut self.velocities, velocities);
        copy_matrix(&mut self.damping, damping);
        copy_matrix(&mut self.armature, armature);
        copy_matrix(&mut self.frictions, frictions);
        copy_matrix(&mut self.accelerations, accelerations);
        self.body_jacobians.truncate(body_jacobians.len());
        for (mine, theirs) in self.body_jacobians.iter_mut().zip(body_jacobians) {
            copy_matrix(mine, theirs);
        }
        let have = self.body_jacobians.len();
        self.body_jacobians
            .extend(body_jacobians[have..].iter().cloned());
        copy_matrix(&mut self.augmented_mass, augmented_mass);
        self.inv_augmented_mass.clone_from(inv_augmented_mass);
        let IndexSequence {
            first_to_remove,
            index_map,
        } = augmented_mass_indices;
        self.augmented_mass_indices.first_to_remove = *first_to_remove;
        self.augmented_mass_indices.index_map.clone_from(index_map);
        copy_matrix(&mut self.acc_augmented_mass, acc_augmented_mass);
        self.acc_inv_augmented_mass
            .clone_from(acc_inv_augmented_mass);
        self.ndofs = *ndofs;
        self.root_is_dynamic = *root_is_dynamic;
        self.solver_id = *solver_id;
        self.self_contacts_enabled = *self_contacts_enabled;
        self.couplings.clone_from(couplings);
        self.kinematics_inputs.clone_from(kinematics_inputs);
        // Scratch (`MultibodyWorkspace`'s `Clone`): its sizes are what a copy must have.
        if !self.workspace.same_sizes(workspace) {
            self.workspace = workspace.clone();
        }
        // Read across calls within a step (`fill_jacobians_unsolved`): never another
        // tree's of the same sizes.
        self.workspace.col_ranges.clone_from(&workspace.col_ranges);
        self.workspace
            .col_ranges_key
            .clone_from(&workspace.col_ranges_key);
    }
}

/// Strider patch: `source` copied into `dest`'s buffer when their shapes match, else
/// cloned: the same values either way.
fn copy_matrix<R: na::Dim, C: na::Dim, S>(
    dest: &mut na::Matrix<Real, R, C, S>,
    source: &na::Matrix<Real, R, C, S>,
) where
    S: na::RawStorageMut<Real, R, C> + na::IsContiguous + Clone,
{
    if dest.shape() == source.shape() {
        dest.as_mut_slice().copy_from_slice(source.as_slice());
    } else {
        *dest = source.clone();
    }
}

impl Multibody {
    /// Creates a new multibody with no link.
    pub fn new() -> Self {
        Self::with_self_contacts(true)
    }

    pub(crate) fn with_self_contacts(self_contacts_enabled: bool) -> Self {
        Multibody {
            links: MultibodyLinkVec(Vec::new()),
            velocities: DVector::zeros(0),
            damping: DVector::zeros(0),
            armature: DVector::zeros(0),
            frictions: DVector::zeros(0),
            accelerations: DVector::zeros(0),
            body_jacobians: Vec::new(),
            augmented_mass: DMatrix::zeros(0, 0),
            inv_augmented_mass: MassFactor::new(),
            acc_augmented_mass: DMatrix::zeros(0, 0),
            acc_inv_augmented_mass: MassFactor::new(),
            augmented_mass_indices: IndexSequence::new(),
            ndofs: 0,
            solver_id: 0,
            workspace: MultibodyWorkspace::new(),
            root_is_dynamic: false,
            self_contacts_enabled,
            couplings: Vec::new(),
            kinematics_inputs: Vec::new(),
            // solver_workspace: Some(SolverWorkspace::new()),
        }
    }

    pub(crate) fn with_root(handle: RigidBodyHandle, self_contacts_enabled: bool) -> Self {
        let mut mb = Multibody::with_self_contacts(self_contacts_enabled);
        // NOTE: we have no way of knowing if the root in fixed at this point, so
        //       we mark it as dynamic and will fix later with `Self::update_root_type`.
        mb.root_is_dynamic = true;
        let joint = MultibodyJoint::free(Pose::IDENTITY);
        mb.add_link(None, joint, handle);
        mb
    }

    pub(crate) fn remove_link(self, to_remove: usize, joint_only: bool) -> Vec<Multibody> {
        let mut result = vec![];
        let mut link2mb = vec![usize::MAX; self.links.len()];
        let mut link_id2new_id = vec![usize::MAX; self.links.len()];
        // Links whose joint is replaced by a fixed one: their DoFs no longer exist.
        let mut joint_replaced = vec![false; self.links.len()];

        // Split multibody and update the set of links and ndofs.
        for (i, mut link) in self.links.0.into_iter().enumerate() {
            let is_new_root = i == 0
                || !joint_only && link.parent_internal_id == to_remove
                || joint_only && i == to_remove;

            if !joint_only && i == to_remove {
                continue;
            } else if is_new_root {
                link2mb[i] = result.len();
                result.push(Multibody::with_self_contacts(self.self_contacts_enabled));
            } else {
                link2mb[i] = link2mb[link.parent_internal_id]
            }

            let curr_mb = &mut result[link2mb[i]];
            link_id2new_id[i] = curr_mb.links.len();

            if is_new_root {
                let joint = MultibodyJoint::fixed(*link.local_to_world());
                link.joint = joint;
                joint_replaced[i] = true;
            }

            curr_mb.ndofs += link.joint().ndofs();
            curr_mb.links.push(link);
        }

        // Adjust all the internal ids, and copy the data from the
        // previous multibody to the new one.
        for mb in &mut result {
            mb.grow_buffers(mb.ndofs, mb.links.len());
            mb.workspace.resize(mb.links.len(), mb.ndofs);

            let mut assembly_id = 0;
            for (i, link) in mb.links.iter_mut().enumerate() {
                let link_ndofs = link.joint().ndofs();
                mb.velocities
                    .rows_mut(assembly_id, link_ndofs)
                    .copy_from(&self.velocities.rows(link.assembly_id, link_ndofs));
                mb.damping
                    .rows_mut(assembly_id, link_ndofs)
                    .copy_from(&self.damping.rows(link.assembly_id, link_ndofs));
                mb.armature
                    .rows_mut(assembly_id, link_ndofs)
                    .copy_from(&self.armature.rows(link.assembly_id, link_ndofs));
                mb.frictions
                    .rows_mut(assembly_id, link_ndofs)
                    .copy_from(&self.frictions.rows(link.assembly_id, link_ndofs));
                mb.accelerations
                    .rows_mut(assembly_id, link_ndofs)
                    .copy_from(&self.accelerations.rows(link.assembly_id, link_ndofs));

                link.internal_id = i;
                link.assembly_id = assembly_id;

                // NOTE: for the root, the current`link.parent_internal_id` is invalid since that
                //       parent lies in a different multibody now.
                link.parent_internal_id = if i != 0 {
                    link_id2new_id[link.parent_internal_id]
                } else {
                    0
                };
                assembly_id += link_ndofs;
            }
        }

        // Keep the couplings whose DoFs still exist and ended up in the same multibody.
        for coupling in &self.couplings {
            let (l1, l2) = (coupling.link1, coupling.link2);
            let kept = |l: usize| link_id2new_id[l] != usize::MAX && !joint_replaced[l];
            if kept(l1) && kept(l2) && link2mb[l1] == link2mb[l2] {
                result[link2mb[l1]].couplings.push(MultibodyDofCoupling {
                    link1: link_id2new_id[l1],
                    link2: link_id2new_id[l2],
                    ..*coupling
                });
            }
        }

        result
    }

    pub(crate) fn append(&mut self, mut rhs: Multibody, parent: usize, joint: MultibodyJoint) {
        let joint_ndofs = joint.ndofs();
        let rhs_root_ndofs = rhs.links[0].joint.ndofs();
        let ndofs_before_append = self.velocities.len();
        let base_internal_id = self.links.len();
        // Values for rhs will be copied into the buffers of `self` starting at this index.
        let rhs_copy_shift = ndofs_before_append + joint_ndofs;
        // Number of dofs to copy from rhs. The root’s dofs isn’t included because it will be
        // replaced by `joint`.
        let rhs_copy_ndofs = rhs.ndofs - rhs_root_ndofs;

        // Adjust the ids of all the rhs links except the first one.
        for link in &mut rhs.links.0[1..] {
            link.assembly_id =
                (link.assembly_id + ndofs_before_append + joint_ndofs) - rhs_root_ndofs;
            link.internal_id += base_internal_id;
            link.parent_internal_id += base_internal_id;
        }

        // Adjust the first link.
        {
            rhs.links[0].joint = joint;
            rhs.links[0].assembly_id = ndofs_before_append;
            rhs.links[0].internal_id = base_internal_id;
            rhs.links[0].parent_internal_id = parent;
        }

        // Grow buffers then append data from rhs.
        self.grow_buffers(rhs_copy_ndofs + joint_ndofs, rhs.links.len());

        if rhs_copy_ndofs > 0 {
            self.velocities
                .rows_mut(rhs_copy_shift, rhs_copy_ndofs)
                .copy_from(&rhs.velocities.rows(rhs_root_ndofs, rhs_copy_ndofs));
            self.damping
                .rows_mut(rhs_copy_shift, rhs_copy_ndofs)
                .copy_from(&rhs.damping.rows(rhs_root_ndofs, rhs_copy_ndofs));
            self.armature
                .rows_mut(rhs_copy_shift, rhs_copy_ndofs)
                .copy_from(&rhs.armature.rows(rhs_root_ndofs, rhs_copy_ndofs));
            self.frictions
                .rows_mut(rhs_copy_shift, rhs_copy_ndofs)
                .copy_from(&rhs.frictions.rows(rhs_root_ndofs, rhs_copy_ndofs));
            self.accelerations
                .rows_mut(rhs_copy_shift, rhs_copy_ndofs)
                .copy_from(&rhs.accelerations.rows(rhs_root_ndofs, rhs_copy_ndofs));
        }

        // Set the default damping for the new joint.
        rhs.links[0]
            .joint
            .default_damping(&mut self.damping.rows_mut(ndofs_before_append, joint_ndofs));

        self.links.append(&mut rhs.links);
        self.ndofs = self.velocities.len();
        self.workspace.resize(self.links.len(), self.ndofs);

        // The rhs couplings follow its links, except the ones on its root whose joint was replaced.
        self.couplings.extend(
            rhs.couplings
                .iter()
                .filter(|c| c.link1 != 0 && c.link2 != 0)
                .map(|c| MultibodyDofCoupling {
                    link1: c.link1 + base_internal_id,
                    link2: c.link2 + base_internal_id,
                    ..*c
                }),
        );
        // Self-contacts stay disabled for the links of a multibody that had them disabled.
        self.self_contacts_enabled &= rhs.self_contacts_enabled;
    }

    /// Whether self-contacts are enabled on this multibody.
    ///
    /// If set to `false` no two link from this multibody can generate contacts, even
    /// if the contact is enabled on the individual joint with [`GenericJoint::contacts_enabled`].
    pub fn self_contacts_enabled(&self) -> bool {
        self.self_contacts_enabled
    }

    /// Sets whether self-contacts are enabled on this multibody.
    ///
    /// If set to `false` no two link from this multibody can generate contacts, even
    /// if the contact is enabled on the individual joint with [`GenericJoint::contacts_enabled`].
    pub fn set_self_contacts_enabled(&mut self, enabled: bool) {
        self.self_contacts_enabled = enabled;
    }

    /// The inverse augmented mass matrix of this multibody (Strider patch: factorised
    /// along the multibody's tree, [`MassFactor`]).
    pub fn inv_augmented_mass(&self) -> &MassFactor {
        &self.inv_augmented_mass
    }

    /// The first link of this multibody.
    #[inline]
    pub fn root(&self) -> &MultibodyLink {
        &self.links[0]
    }

    /// Mutable reference to the first link of this multibody.
    #[inline]
    pub fn root_mut(&mut self) -> &mut MultibodyLink {
        &mut self.links[0]
    }

    /// Reference `i`-th multibody link of this multibody.
    ///
    /// Return `None` if there is less than `i + 1` multibody links.
    #[inline]
    pub fn link(&self, id: usize) -> Option<&MultibodyLink> {
        self.links.get(id)
    }

    /// Mutable reference to the multibody link with the given id.
    ///
    /// Return `None` if the given id does not identifies a multibody link part of `self`.
    #[inline]
    pub fn link_mut(&mut self, id: usize) -> Option<&mut MultibodyLink> {
        self.links.get_mut(id)
    }

    /// The number of links on this multibody.
    pub fn num_links(&self) -> usize {
        self.links.len()
    }

    /// Iterator through all the links of this multibody.
    ///
    /// All link are guaranteed to be yielded before its descendant.
    pub fn links(&self) -> impl Iterator<Item = &MultibodyLink> {
        self.links.iter()
    }

    /// Mutable iterator through all the links of this multibody.
    ///
    /// All link are guaranteed to be yielded before its descendant.
    pub fn links_mut(&mut self) -> impl Iterator<Item = &mut MultibodyLink> {
        self.links.iter_mut()
    }

    /// The vector of damping applied to this multibody.
    #[inline]
    pub fn damping(&self) -> &DVector {
        &self.damping
    }

    /// Mutable vector of damping applied to this multibody.
    #[inline]
    pub fn damping_mut(&mut self) -> &mut DVector {
        &mut self.damping
    }

    /// The vector of per-DoF armature (reflected rotor inertia) of this multibody: additional
    /// inertia added directly to the mass matrix, simulating the joint's own weight distribution.
    #[inline]
    pub fn armature(&self) -> &DVector {
        &self.armature
    }

    /// Mutable vector of per-DoF armature (reflected rotor inertia) of this
    /// multibody.
    #[inline]
    pub fn armature_mut(&mut self) -> &mut DVector {
        &mut self.armature
    }

    /// The vector of per-DoF dry joint friction (MuJoCo's `frictionloss`, in N
    /// or N·m): the largest force friction may generate on that DoF.
    #[inline]
    pub fn frictions(&self) -> &DVector {
        &self.frictions
    }

    /// Mutable vector of per-DoF dry joint friction of this multibody.
    #[inline]
    pub fn frictions_mut(&mut self) -> &mut DVector {
        &mut self.frictions
    }

    pub(crate) fn add_link(
        &mut self,
        parent: Option<usize>, // TODO: should be a RigidBodyHandle?
        dof: MultibodyJoint,
        body: RigidBodyHandle,
    ) -> &mut MultibodyLink {
        assert!(
            parent.is_none() || !self.links.is_empty(),
            "Multibody::build_body: invalid parent id."
        );

        /*
         * Compute the indices.
         */
        let assembly_id = self.velocities.len();
        let internal_id = self.links.len();

        /*
         * Grow the buffers.
         */
        let ndofs = dof.ndofs();
        self.grow_buffers(ndofs, 1);
        self.ndofs += ndofs;

        /*
         * Setup default damping.
         */
        dof.default_damping(&mut self.damping.rows_mut(assembly_id, ndofs));

        /*
         * Create the multibody.
         */
        let local_to_parent = dof.body_to_parent();
        let local_to_world;

        let parent_internal_id;
        if let Some(parent) = parent {
            parent_internal_id = parent;
            let parent_link = &mut self.links[parent_internal_id];
            local_to_world = parent_link.local_to_world * local_to_parent;
        } else {
            parent_internal_id = 0;
            local_to_world = local_to_parent;
        }

        let rb = MultibodyLink::new(
            body,
            internal_id,
            assembly_id,
            parent_internal_id,
            dof,
            local_to_world,
            local_to_parent,
        );

        self.links.push(rb);
        self.workspace.resize(self.links.len(), self.ndofs);

        &mut self.links[internal_id]
    }

    fn grow_buffers(&mut self, ndofs: usize, num_jacobians: usize) {
        let len = self.velocities.len();
        self.velocities.resize_vertically_mut(len + ndofs, 0.0);
        self.damping.resize_vertically_mut(len + ndofs, 0.0);
        self.armature.resize_vertically_mut(len + ndofs, 0.0);
        self.frictions.resize_vertically_mut(len + ndofs, 0.0);
        self.accelerations.resize_vertically_mut(len + ndofs, 0.0);
        self.body_jacobians
            .extend((0..num_jacobians).map(|_| Jacobian::zeros(0)));
    }

    pub(crate) fn update_acceleration(&mut self, dt: Real, bodies: &RigidBodySet) {
        if self.ndofs == 0 {
            return; // Nothing to do.
        }

        self.accelerations.as_mut_slice().fill(0.0);

        // If there is significant movement, the semi-implicit coriolis term
        // occasionally cause instabilities due to the matrix being near singular.
        // To prevent that, we enable a check that verifies the result and fallbacks
        // to the explicit term if needed
        let check_implicit_coriolis_divergence = dt * self.velocities.amax() >= 1.0e-3;
        // Generalized forces that derive from positions or external inputs
        // (gravity, user forces, spring position terms).
        // Strider patch: this vector and the copy of the forces below are the workspace's,
        // not allocated each step; they are written here before anything reads them.
        let mut pos_forces = core::mem::take(&mut self.workspace.pos_forces);
        if check_implicit_coriolis_divergence {
            scratch_zeros(&mut pos_forces, self.ndofs);
        }

        // Strider patch: a link's body Jacobian is zero outside the columns of its own and
        // its ancestors' dofs (`link_column_ranges`), so its forces reach only those
        // generalised forces. Over the other columns upstream's `gemv_tr` added `1·(+0)` (a
        // dot product of a zero column with finite forces) to an entry that started at +0,
        // which leaves it unchanged: the same bits (docs/rapier.md, "Mass-matrix sparsity").
        let col_ranges = self.workspace.column_ranges(&self.links);

        // Eqn 42 to 45
        for i in 0..self.links.len() {
            let link = &self.links[i];
            let rb = &bodies[link.rigid_body];

            let mut acc = RigidBodyVelocity::zero();

            if i != 0 {
                let parent_id = link.parent_internal_id;
                let parent_link = &self.links[parent_id];
                let parent_rb = &bodies[parent_link.rigid_body];

                acc += self.workspace.accs[parent_id];
                // The 2.0 originates from the two identical terms of Jdot (the terms become
                // identical once they are multiplied by the generalized velocities).
                acc.linvel += 2.0 * parent_rb.vels.angvel.gcross(link.joint_velocity.linvel);
                #[cfg(feature = "dim3")]
                {
                    acc.angvel += parent_rb.vels.angvel.cross(link.joint_velocity.angvel);
                }

                acc.linvel += parent_rb
                    .vels
                    .angvel
                    .gcross(parent_rb.vels.angvel.gcross(link.shift02));
                acc.linvel += self.workspace.accs[parent_id].angvel.gcross(link.shift02);
            }

            acc.linvel += rb.vels.angvel.gcross(rb.vels.angvel.gcross(link.shift23));
            acc.linvel += acc.angvel.gcross(link.shift23);

            self.workspace.accs[i] = acc;

            // TODO: should gyroscopic forces already be computed by the rigid-body itself
            //       (at the same time that we add the gravity force)?
            let gyroscopic;
            let rb_inertia = rb.mprops.effective_angular_inertia();
            let rb_mass = rb.mprops.effective_mass();

            #[cfg(feature = "dim3")]
            {
                let angvel = rb.vels.angvel;
                let inertia_times_angvel = rb_inertia * angvel;
                gyroscopic = angvel.cross(inertia_times_angvel);
            }
            #[cfg(feature = "dim2")]
            {
                gyroscopic = 0.0;
            }

            let external_forces = Force::new(
                rb.forces.force - rb_mass * acc.linvel,
                rb.forces.torque - gyroscopic - rb_inertia * acc.angvel,
            );
            add_transposed_product(
                &mut self.accelerations,
                &self.body_jacobians[i],
                external_forces.as_vector(),
                &col_ranges[i],
            );

            if check_implicit_coriolis_divergence {
                let applied_forces = Force::new(rb.forces.force, rb.forces.torque);
                add_transposed_product(
                    &mut pos_forces,
                    &self.body_jacobians[i],
                    applied_forces.as_vector(),
                    &col_ranges[i],
                );
            }
        }
        self.workspace.col_ranges = col_ranges;

        self.accelerations
            .cmpy(-1.0, &self.damping, &self.velocities, 1.0);

        // Implicit joint springs: backward-Euler at `q⁺ = q + dt·v⁺` gives `-k·(q − rest) − k·dt·v⁺`,
        // with the `v⁺` part implicit via the `dt²·k` mass-matrix diagonal (see `update_mass_matrix`).
        // Consistency requires BOTH `-k·(q − rest)` and `-k·dt·v` here, else the spring is only semi-implicit.
        for li in 0..self.links.len() {
            let mut idx = self.links[li].assembly_id;
            let locked = self.links[li].joint.data.locked_axes.bits();
            for a in 0..SPATIAL_DIM {
                if (locked >> a) & 1 == 0 {
                    let k = self.links[li].joint.spring_stiffness[a];
                    if k != 0.0 {
                        let q = self.links[li].joint.coords[a];
                        let rest = self.links[li].joint.spring_ref[a];
                        let spring_pos_force = -k * (q - rest);
                        self.accelerations[idx] += spring_pos_force - k * dt * self.velocities[idx];
                        if check_implicit_coriolis_divergence {
                            pos_forces[idx] += spring_pos_force;
                        }
                    }
                    idx += 1;
                }
            }
        }

        // Snapshot the full generalized forces: the energy guard may need them
        // for a re-solve with the plain mass matrix.
        let mut gen_forces = core::mem::take(&mut self.workspace.gen_forces);
        if check_implicit_coriolis_divergence {
            copy_matrix(&mut gen_forces, &self.accelerations);
        }

        self.augmented_mass_indices
            .with_rearranged_rows_mut(&mut self.accelerations, |accs| {
                self.acc_inv_augmented_mass.solve_mut(accs);
            });

        if check_implicit_coriolis_divergence {
            self.free_velocity_energy_guard(dt, &gen_forces, &pos_forces);
        }
        self.workspace.pos_forces = pos_forces;
        self.workspace.gen_forces = gen_forces;
    }

    // If the semi-implicit coriolis solve introduces more energy than the external
    // forces’ work, we recalculate without the coriolis term in the mass matrix.
    //
    // This operates by calculating the effective kinematic energy added by the
    // external forces after the solve with the semi-implicit mass matrix, and
    // compare it with the force’s work. If the energy delta exceeds a threshold
    // (indicating undesired/unrealistic energy injection), we fall back to re-solving
    // the forces effect but using only the mass matrix without the implicit coriolis
    // terms.
    fn free_velocity_energy_guard(&mut self, dt: Real, gen_forces: &DVector, pos_forces: &DVector) {
        let eff_dim = self.augmented_mass_indices.dim_after_removal(self.ndofs);
        if eff_dim == 0 {
            return;
        }

        // Strider patch: the test on the vectors themselves where no dof is kinematic (none
        // of ours): nothing to rearrange, and the two products go into the workspace's
        // buffers. The same `gemv` as upstream's `m * &a` and `m * v` (nalgebra multiplies
        // by a one-column matrix through it), on the same values: the same bits
        // (`energy_guard_in_place_*`). With kinematic dofs, on rearranged copies as upstream.
        let m = self.augmented_mass.view((0, 0), (eff_dim, eff_dim));
        let products = &mut self.workspace.guard_products;
        let excess = if self.augmented_mass_indices.first_to_remove == IndexSequence::NONE {
            energy_excess_in_place(
                m,
                &self.velocities,
                gen_forces,
                pos_forces,
                &self.accelerations,
                dt,
                products,
            )
        } else {
            // Move all quantities to the kinematic-reduced ordering of the
            // factorized matrices.
            let reduced = |x: &DVector| {
                let mut x = x.clone();
                self.augmented_mass_indices.rearrange_rows(&mut x, true);
                x.rows(0, eff_dim).into_owned()
            };
            energy_excess_in_place(
                m,
                &reduced(&self.velocities),
                &reduced(gen_forces),
                &reduced(pos_forces),
                &reduced(&self.accelerations),
                dt,
                products,
            )
        };
        // Otherwise the implicit update introduced too much extra energy.
        if !excess.is_some_and(|e| e <= 0.0) {
            self.fall_back_to_plain_mass(gen_forces);
        }
    }

    /// The implicit solve injected energy (or produced non-finite values): the
    /// accelerations again from `gen_forces`, with the plain mass matrix.
    fn fall_back_to_plain_mass(&mut self, gen_forces: &DVector) {
        self.accelerations.copy_from(gen_forces);
        self.augmented_mass_indices
            .with_rearranged_rows_mut(&mut self.accelerations, |accs| {
                self.inv_augmented_mass.solve_mut(accs);
            });

        // Last-chance check: if all else fails, just clear the accelerations vector
        // instead of breaking the simulation. Hopefully it will get back to a
        // sane result in a close timestep.
        if !self.accelerations.iter().all(|x| x.is_finite()) {
            self.accelerations.fill(0.0);
        }
    }

    /// Computes the constant terms of the dynamics.
    #[profiling::function]
    pub(crate) fn update_velocities(&mut self, bodies: &mut RigidBodySet) {
        /*
         * Compute velocities.
         * NOTE: this is needed for kinematic bodies too.
         */
        let link = &mut self.links[0];
        let joint_velocity = link
            .joint
            .jacobian_mul_coordinates(&self.velocities.as_slice()[link.assembly_id..]);

        link.joint_velocity = joint_velocity;
        bodies.index_mut_internal(link.rigid_body).vels = link.joint_velocity;

        for i in 1..self.links.len() {
            let (link, parent_link) = self.links.get_mut_with_parent(i);
            let rb = &bodies[link.rigid_body];
            let parent_rb = &bodies[parent_link.rigid_body];

            let joint_velocity = link
                .joint
                .jacobian_mul_coordinates(&self.velocities.as_slice()[link.assembly_id..]);
            link.joint_velocity = joint_velocity.transformed(
                &(parent_link.local_to_world.rotation * link.joint.data.local_frame1.rotation),
            );
            let mut new_rb_vels = parent_rb.vels + link.joint_velocity;
            let shift = rb.mprops.world_com - parent_rb.mprops.world_com;
            new_rb_vels.linvel += parent_rb.vels.angvel.gcross(shift);
            new_rb_vels.linvel += link.joint_velocity.angvel.gcross(link.shift23);

            bodies.index_mut_internal(link.rigid_body).vels = new_rb_vels;
        }
    }

    fn update_body_jacobians(&mut self) {
        // Strider patch: a link's body Jacobian is zero outside the columns of its own and
        // its ancestors' dofs (its `ranges`, as in `update_mass_matrix`), so the two
        // products below are done over those columns only. Outside them both operands are
        // zero and the dense product left +0, which the copy from the parent already holds:
        // the same bits.
        let ranges = self.workspace.column_ranges(&self.links);
        for i in 0..self.links.len() {
            let link = &self.links[i];
            if self.body_jacobians[i].ncols() != self.ndofs {
                // TODO: use a resize instead.
                self.body_jacobians[i] = Jacobian::zeros(self.ndofs);
            }

            let parent_to_world;

            if i != 0 {
                let parent_id = link.parent_internal_id;
                let parent_link = &self.links[parent_id];
                parent_to_world = parent_link.local_to_world;

                let (link_j, parent_j) = self.body_jacobians.index_mut_const(i, parent_id);
                // Strider patch: one slice copy (nalgebra's `copy_from` goes element by
                // element through a strided loop).
                link_j.as_mut_slice().copy_from_slice(parent_j.as_slice());

                {
                    let mut link_j_v = link_j.fixed_rows_mut::<DIM>(0);
                    let parent_j_w = parent_j.fixed_rows::<ANG_DIM>(DIM);

                    let shift_tr = vect_to_na(link.shift02).gcross_matrix_tr();
                    for &(s, n) in &ranges[parent_id] {
                        link_j_v.columns_mut(s, n).gemm(
                            1.0,
                            &shift_tr,
                            &parent_j_w.columns(s, n),
                            1.0,
                        );
                    }
                }
            } else {
                self.body_jacobians[i].as_mut_slice().fill(0.0);
                parent_to_world = Pose::IDENTITY;
            }

            let ndofs = link.joint.ndofs();
            let mut tmp = SMatrix::<Real, SPATIAL_DIM, SPATIAL_DIM>::zeros();
            let mut link_joint_j = tmp.columns_mut(0, ndofs);
            let mut link_j_part = self.body_jacobians[i].columns_mut(link.assembly_id, ndofs);
            link.joint.jacobian(
                &(parent_to_world.rotation * link.joint.data.local_frame1.rotation),
                &mut link_joint_j,
            );
            link_j_part += link_joint_j;

            {
                let link_j = &mut self.body_jacobians[i];
                let (mut link_j_v, link_j_w) =
                    link_j.rows_range_pair_mut(0..DIM, DIM..DIM + ANG_DIM);
                let shift_tr = vect_to_na(link.shift23).gcross_matrix_tr();
                for &(s, n) in &ranges[i] {
                    link_j_v
                        .columns_mut(s, n)
                        .gemm(1.0, &shift_tr, &link_j_w.columns(s, n), 1.0);
                }
            }
        }
        self.workspace.col_ranges = ranges;
    }

    /// The upstream dense body Jacobians, the reference the sparse ones are tested against.
    #[cfg(test)]
    fn update_body_jacobians_dense(&mut self) {
        for i in 0..self.links.len() {
            let link = &self.links[i];

            if self.body_jacobians[i].ncols() != self.ndofs {
                self.body_jacobians[i] = Jacobian::zeros(self.ndofs);
            }

            let parent_to_world;

            if i != 0 {
                let parent_id = link.parent_internal_id;
                let parent_link = &self.links[parent_id];
                parent_to_world = parent_link.local_to_world;

                let (link_j, parent_j) = self.body_jacobians.index_mut_const(i, parent_id);
                link_j.copy_from(parent_j);

                {
                    let mut link_j_v = link_j.fixed_rows_mut::<DIM>(0);
                    let parent_j_w = parent_j.fixed_rows::<ANG_DIM>(DIM);

                    let shift_tr = vect_to_na(link.shift02).gcross_matrix_tr();
                    link_j_v.gemm(1.0, &shift_tr, &parent_j_w, 1.0);
                }
            } else {
                self.body_jacobians[i].as_mut_slice().fill(0.0);
                parent_to_world = Pose::IDENTITY;
            }

            let ndofs = link.joint.ndofs();
            let mut tmp = SMatrix::<Real, SPATIAL_DIM, SPATIAL_DIM>::zeros();
            let mut link_joint_j = tmp.columns_mut(0, ndofs);
            let mut link_j_part = self.body_jacobians[i].columns_mut(link.assembly_id, ndofs);
            link.joint.jacobian(
                &(parent_to_world.rotation * link.joint.data.local_frame1.rotation),
                &mut link_joint_j,
            );
            link_j_part += link_joint_j;

            {
                let link_j = &mut self.body_jacobians[i];
                let (mut link_j_v, link_j_w) =
                    link_j.rows_range_pair_mut(0..DIM, DIM..DIM + ANG_DIM);
                let shift_tr = vect_to_na(link.shift23).gcross_matrix_tr();
                link_j_v.gemm(1.0, &shift_tr, &link_j_w, 1.0);
            }
        }
    }

    /// The upstream dense assembly, the reference the sparse one is tested against.
    #[cfg(test)]
    fn update_mass_matrix_dense(
        &mut self,
        dt: Real,
        bodies: &RigidBodySet,
    ) -> (
        Vec<OMatrix<Real, Dim, Dyn>>,
        Vec<OMatrix<Real, AngDim, Dyn>>,
        Vec<Jacobian<Real>>,
    ) {
        if self.ndofs == 0 {
            return (Vec::new(), Vec::new(), Vec::new()); // Nothing to do.
        }

        if self.augmented_mass.ncols() != self.ndofs {
            // TODO: do a resize instead of a full reallocation.
            self.augmented_mass = DMatrix::zeros(self.ndofs, self.ndofs);
            self.acc_augmented_mass = DMatrix::zeros(self.ndofs, self.ndofs);
        } else {
            self.augmented_mass.fill(0.0);
            self.acc_augmented_mass.fill(0.0);
        }

        self.augmented_mass_indices.clear();

        // Strider patch: upstream's Coriolis workspaces, here only (returned for the tests).
        let mut cor_v = vec![OMatrix::<Real, Dim, Dyn>::zeros(self.ndofs); self.links.len()];
        let mut cor_w = vec![OMatrix::<Real, AngDim, Dyn>::zeros(self.ndofs); self.links.len()];
        let mut i_coriolis_dt = Jacobian::zeros(self.ndofs);
        let mut melded = Vec::with_capacity(self.links.len());

        let mut curr_assembly_id = 0;

        for i in 0..self.links.len() {
            let link = &self.links[i];
            let rb = &bodies[link.rigid_body];
            let rb_mass = rb.mprops.effective_mass();
            let rb_inertia = rb.mprops.effective_angular_inertia().into_matrix();
            let body_jacobian = &self.body_jacobians[i];

            // NOTE: the mass matrix index reordering operates on the assumption that the assembly
            //       ids are traversed in order. This assert is here to ensure the assumption always
            //       hold.
            assert_eq!(
                curr_assembly_id, link.assembly_id,
                "Internal error: contiguity assumption on assembly_id does not hold."
            );
            curr_assembly_id += link.joint.ndofs();

            if link.joint.kinematic {
                for k in link.assembly_id..link.assembly_id + link.joint.ndofs() {
                    self.augmented_mass_indices.remove(k);
                }
            } else {
                for k in link.assembly_id..link.assembly_id + link.joint.ndofs() {
                    self.augmented_mass_indices.keep(k);
                }
            }

            #[allow(unused_mut)] // mut is needed for 3D but not for 2D.
            let mut augmented_inertia = rb_inertia;

            #[cfg(feature = "dim3")]
            {
                // Derivative of gyroscopic forces.
                let gyroscopic_matrix = rb.vels.angvel.gcross_matrix() * rb_inertia
                    - (rb_inertia * rb.vels.angvel).gcross_matrix();

                augmented_inertia += gyroscopic_matrix * dt;
            }

            // TODO: optimize that (knowing the structure of the augmented inertia matrix).
            // TODO: this could be better optimized in 2D.
            #[allow(clippy::useless_conversion)] // Needed in 3D, no-op in 2D
            let rb_mass_matrix_wo_gyro = concat_rb_mass_matrix(rb_mass, rb_inertia.into());
            #[allow(clippy::useless_conversion)] // Needed in 3D, no-op in 2D
            let rb_mass_matrix = concat_rb_mass_matrix(rb_mass, augmented_inertia.into());
            self.augmented_mass
                .quadform(1.0, &rb_mass_matrix_wo_gyro, body_jacobian, 1.0);
            self.acc_augmented_mass
                .quadform(1.0, &rb_mass_matrix, body_jacobian, 1.0);

            /*
             *
             * Coriolis matrix.
             *
             */
            let rb_j = &self.body_jacobians[i];
            let rb_j_w = rb_j.fixed_rows::<ANG_DIM>(DIM);

            let ndofs = link.joint.ndofs();

            if i != 0 {
                let parent_id = link.parent_internal_id;
                let parent_link = &self.links[parent_id];
                let parent_rb = &bodies[parent_link.rigid_body];
                let parent_j = &self.body_jacobians[parent_id];
                let parent_j_w = parent_j.fixed_rows::<ANG_DIM>(DIM);
                let parent_w = SimdAngVector::<Real>::from(parent_rb.vels.angvel).gcross_matrix();

                let (coriolis_v, parent_coriolis_v) = cor_v.index_mut2(i, parent_id);
                let (coriolis_w, parent_coriolis_w) = cor_w.index_mut2(i, parent_id);

                coriolis_v.copy_from(parent_coriolis_v);
                coriolis_w.copy_from(parent_coriolis_w);

                // [c1 - c0].gcross() * (JDot + JDot/u * qdot)"
                let shift_cross_tr = vect_to_na(link.shift02).gcross_matrix_tr();
                coriolis_v.gemm(1.0, &shift_cross_tr, parent_coriolis_w, 1.0);

                // JDot (but the 2.0 originates from the sum of two identical terms in JDot and JDot/u * gdot)
                let dvel_cross = vect_to_na(
                    rb.vels.angvel.gcross(link.shift02) + 2.0 * link.joint_velocity.linvel,
                )
                .gcross_matrix_tr();
                coriolis_v.gemm(1.0, &dvel_cross, &parent_j_w, 1.0);

                // JDot/u * qdot
                coriolis_v.gemm(
                    1.0,
                    &vect_to_na(link.joint_velocity.linvel).gcross_matrix_tr(),
                    &parent_j_w,
                    1.0,
                );
                coriolis_v.gemm(1.0, &(parent_w * shift_cross_tr), &parent_j_w, 1.0);

                #[cfg(feature = "dim3")]
                {
                    let vel_wrt_joint_w = vect_to_na(link.joint_velocity.angvel).gcross_matrix();
                    coriolis_w.gemm(-1.0, &vel_wrt_joint_w, &parent_j_w, 1.0);
                }

                // JDot (but the 2.0 originates from the sum of two identical terms in JDot and JDot/u * gdot)
                if !link.joint.kinematic {
                    let mut coriolis_v_part = coriolis_v.columns_mut(link.assembly_id, ndofs);

                    let mut tmp1 = SMatrix::<Real, SPATIAL_DIM, SPATIAL_DIM>::zeros();
                    let mut rb_joint_j = tmp1.columns_mut(0, ndofs);
                    link.joint.jacobian(
                        &(parent_link.local_to_world.rotation
                            * link.joint.data.local_frame1.rotation),
                        &mut rb_joint_j,
                    );

                    let rb_joint_j_v = rb_joint_j.fixed_rows::<DIM>(0);
                    coriolis_v_part.gemm(2.0, &parent_w, &rb_joint_j_v, 1.0);

                    #[cfg(feature = "dim3")]
                    {
                        let rb_joint_j_w = rb_joint_j.fixed_rows::<ANG_DIM>(DIM);
                        let mut coriolis_w_part = coriolis_w.columns_mut(link.assembly_id, ndofs);
                        coriolis_w_part.gemm(1.0, &parent_w, &rb_joint_j_w, 1.0);
                    }
                }
            } else {
                cor_v[i].fill(0.0);
                cor_w[i].fill(0.0);
            }

            let coriolis_v = &mut cor_v[i];
            let coriolis_w = &mut cor_w[i];

            {
                // [c3 - c2].gcross() * (JDot + JDot/u * qdot)
                let shift_cross_tr = vect_to_na(link.shift23).gcross_matrix_tr();
                coriolis_v.gemm(1.0, &shift_cross_tr, coriolis_w, 1.0);

                // JDot
                let dvel_cross = vect_to_na(rb.vels.angvel.gcross(link.shift23)).gcross_matrix_tr();
                coriolis_v.gemm(1.0, &dvel_cross, &rb_j_w, 1.0);

                // JDot/u * qdot
                coriolis_v.gemm(
                    1.0,
                    &(SimdAngVector::<Real>::from(rb.vels.angvel).gcross_matrix() * shift_cross_tr),
                    &rb_j_w,
                    1.0,
                );
            }

            let coriolis_v = &mut cor_v[i];
            let coriolis_w = &mut cor_w[i];

            /*
             * Meld with the mass matrix.
             */
            {
                let mut i_coriolis_dt_v = i_coriolis_dt.fixed_rows_mut::<DIM>(0);
                i_coriolis_dt_v.copy_from(coriolis_v);
                let rb_mass_dt = vect_to_na(rb_mass * dt);
                i_coriolis_dt_v
                    .column_iter_mut()
                    .for_each(|mut c| c.component_mul_assign(&rb_mass_dt));
            }

            #[cfg(feature = "dim2")]
            {
                let mut i_coriolis_dt_w = i_coriolis_dt.fixed_rows_mut::<ANG_DIM>(DIM);
                // NOTE: this is just an axpy, but on row columns.
                i_coriolis_dt_w.zip_apply(coriolis_w, |o, x| *o = x * dt * rb_inertia);
            }
            #[cfg(feature = "dim3")]
            {
                let mut i_coriolis_dt_w = i_coriolis_dt.fixed_rows_mut::<ANG_DIM>(DIM);
                i_coriolis_dt_w.gemm(dt, &mat_to_na(rb_inertia), coriolis_w, 0.0);
            }

            self.acc_augmented_mass
                .gemm_tr(1.0, rb_j, &i_coriolis_dt, 1.0);
            melded.push(i_coriolis_dt.clone());
        }

        /*
         * Damping and armature.
         *
         * Damping is a velocity-proportional force made implicit, so it adds
         * `dt · d` to the mass-matrix diagonal. Armature is a "reflected
         * rotor inertia" (additional inertia to account for the joint’s
         * mass and geometry itself): it adds to the diagonal directly.
         */
        for i in 0..self.ndofs {
            let diag = self.damping[i] * dt + self.armature[i];
            self.acc_augmented_mass[(i, i)] += diag;
            self.augmented_mass[(i, i)] += diag;
        }

        // Implicit joint springs: `dt²·k` on the mass-matrix diagonal (force term in `update_acceleration`)
        // keeps a stiff spring on a low-inertia link stable where an explicit position motor injects energy.
        // The spring lives on the link's `MultibodyJoint` so it travels with the link through topology changes.
        let dt2 = dt * dt;
        for li in 0..self.links.len() {
            let mut idx = self.links[li].assembly_id;
            let locked = self.links[li].joint.data.locked_axes.bits();
            for a in 0..SPATIAL_DIM {
                if (locked >> a) & 1 == 0 {
                    let k = self.links[li].joint.spring_stiffness[a];
                    if k != 0.0 {
                        let d = k * dt2;
                        self.acc_augmented_mass[(idx, idx)] += d;
                        self.augmented_mass[(idx, idx)] += d;
                    }
                    idx += 1;
                }
            }
        }

        let effective_dim = self
            .augmented_mass_indices
            .dim_after_removal(self.acc_augmented_mass.nrows());

        // PERF: since we clone the matrix anyway for LU, should be directly output
        //       a new matrix instead of applying permutations?
        self.augmented_mass_indices
            .rearrange_columns(&mut self.acc_augmented_mass, true);
        self.augmented_mass_indices
            .rearrange_columns(&mut self.augmented_mass, true);

        self.augmented_mass_indices
            .rearrange_rows(&mut self.acc_augmented_mass, true);
        self.augmented_mass_indices
            .rearrange_rows(&mut self.augmented_mass, true);

        // TODO: avoid allocation inside LU at each timestep.
        self.acc_inv_augmented_mass.set_dense(
            self.acc_augmented_mass
                .view((0, 0), (effective_dim, effective_dim))
                .into_owned(),
        );
        self.inv_augmented_mass.set_dense(
            self.augmented_mass
                .view((0, 0), (effective_dim, effective_dim))
                .into_owned(),
        );
        (cor_v, cor_w, melded)
    }

    pub(crate) fn update_mass_matrix(&mut self, dt: Real, bodies: &RigidBodySet) {
        if self.ndofs == 0 {
            return; // Nothing to do.
        }

        if self.augmented_mass.ncols() != self.ndofs {
            // TODO: do a resize instead of a full reallocation.
            self.augmented_mass = DMatrix::zeros(self.ndofs, self.ndofs);
            self.acc_augmented_mass = DMatrix::zeros(self.ndofs, self.ndofs);
        } else {
            self.augmented_mass.as_mut_slice().fill(0.0);
            self.acc_augmented_mass.as_mut_slice().fill(0.0);
        }

        self.augmented_mass_indices.clear();

        let mut curr_assembly_id = 0;

        // Strider patch: a link's body Jacobian is zero outside the columns of its own and
        // its ancestors' dofs, so each link's `Jᵀ M J` and `Jᵀ C` only touch those rows and
        // columns. Assemble them over the nonzero column ranges instead of the full
        // `ndofs x ndofs` products (docs/rapier.md, "Mass-matrix sparsity").
        let col_ranges = self.workspace.column_ranges(&self.links);
        // `M J` for each of the two mass matrices.
        let [mut work, mut acc_work] = core::mem::take(&mut self.workspace.mass_work);
        if work.ncols() != self.ndofs {
            work = Jacobian::zeros(self.ndofs);
            acc_work = Jacobian::zeros(self.ndofs);
        }
        // Each link's body Jacobian, its nonzero columns laid out for
        // `transposed_products_add` (a child reads its parent's for its Coriolis terms),
        // and its Coriolis terms in the same layout.
        let mut jt = core::mem::take(&mut self.workspace.jacobian_blocks);
        jt.resize_with(self.links.len(), Vec::new);
        let mut coriolis = core::mem::take(&mut self.workspace.coriolis);
        coriolis.resize_with(self.links.len(), Vec::new);
        let ld = self.ndofs;

        for i in 0..self.links.len() {
            let link = &self.links[i];
            let rb = &bodies[link.rigid_body];
            let rb_mass = rb.mprops.effective_mass();
            let rb_inertia = rb.mprops.effective_angular_inertia().into_matrix();
            let body_jacobian = &self.body_jacobians[i];

            // NOTE: the mass matrix index reordering operates on the assumption that the assembly
            //       ids are traversed in order. This assert is here to ensure the assumption always
            //       hold.
            assert_eq!(
                curr_assembly_id, link.assembly_id,
                "Internal error: contiguity assumption on assembly_id does not hold."
            );
            curr_assembly_id += link.joint.ndofs();

            if link.joint.kinematic {
                for k in link.assembly_id..link.assembly_id + link.joint.ndofs() {
                    self.augmented_mass_indices.remove(k);
                }
            } else {
                for k in link.assembly_id..link.assembly_id + link.joint.ndofs() {
                    self.augmented_mass_indices.keep(k);
                }
            }

            #[allow(unused_mut)] // mut is needed for 3D but not for 2D.
            let mut augmented_inertia = rb_inertia;

            #[cfg(feature = "dim3")]
            {
                // Derivative of gyroscopic forces.
                let gyroscopic_matrix = rb.vels.angvel.gcross_matrix() * rb_inertia
                    - (rb_inertia * rb.vels.angvel).gcross_matrix();

                augmented_inertia += gyroscopic_matrix * dt;
            }

            // TODO: optimize that (knowing the structure of the augmented inertia matrix).
            // TODO: this could be better optimized in 2D.
            #[allow(clippy::useless_conversion)] // Needed in 3D, no-op in 2D
            let rb_mass_matrix_wo_gyro = concat_rb_mass_matrix(rb_mass, rb_inertia.into());
            #[allow(clippy::useless_conversion)] // Needed in 3D, no-op in 2D
            let rb_mass_matrix = concat_rb_mass_matrix(rb_mass, augmented_inertia.into());
            let ranges = &col_ranges[i];
            transpose_columns(&mut jt[i], body_jacobian, ranges);
            for &(sb, nb) in ranges {
                spatial_product(&mut work, &rb_mass_matrix_wo_gyro, body_jacobian, sb, nb);
                spatial_product(&mut acc_work, &rb_mass_matrix, body_jacobian, sb, nb);
            }

            /*
             *
             * Coriolis matrix.
             *
             */
            // Strider patch: the link's Coriolis terms (`coriolis_v` over `coriolis_w`)
            // over its nonzero columns only, in `jt`'s layout (blocks of `LANES` columns
            // side by side), so each 3x3 product below runs `LANES` columns at a time. A
            // parent's columns are the first of its child's (`link_column_ranges`), so
            // parent and child blocks line up. Outside a link's columns upstream's dense
            // terms are +0; each entry inside has nalgebra's `gemm` arithmetic (column by
            // column through `gemv`, see `add_product`): the same bits.
            let ndofs = link.joint.ndofs();
            let width: usize = ranges.iter().map(|r| r.1).sum();
            let mut cor = core::mem::take(&mut coriolis[i]);
            // Every entry is written below (the root's zeroed).
            cor.resize(jt[i].len(), 0.0);
            if i == 0 {
                cor.fill(0.0);
            } else {
                let parent_id = link.parent_internal_id;
                let parent_link = &self.links[parent_id];
                let parent_rb = &bodies[parent_link.rigid_body];
                let parent_w = SimdAngVector::<Real>::from(parent_rb.vels.angvel).gcross_matrix();
                let parent_width: usize = col_ranges[parent_id].iter().map(|r| r.1).sum();

                let shift_cross_tr = vect_to_na(link.shift02).gcross_matrix_tr();
                // JDot (but the 2.0 originates from the sum of two identical terms in JDot and JDot/u * gdot)
                let dvel_cross = vect_to_na(
                    rb.vels.angvel.gcross(link.shift02) + 2.0 * link.joint_velocity.linvel,
                )
                .gcross_matrix_tr();
                let lin_cross = vect_to_na(link.joint_velocity.linvel).gcross_matrix_tr();
                let parent_w_shift = parent_w * shift_cross_tr;
                let vel_wrt_joint_w = vect_to_na(link.joint_velocity.angvel).gcross_matrix();

                // cv = parent cv + [c1 - c0].gcross() * parent cw (JDot + JDot/u * qdot)
                //      + dvel_cross, lin_cross and parent_w_shift times parent jw in turn;
                // cw = parent cw - vel_wrt_joint_w * parent jw.
                coriolis_from_parent(
                    &mut cor,
                    &coriolis[parent_id],
                    &jt[parent_id],
                    parent_width,
                    &[
                        scaled(1.0, &shift_cross_tr),
                        scaled(1.0, &dvel_cross),
                        scaled(1.0, &lin_cross),
                        scaled(1.0, &parent_w_shift),
                        scaled(-1.0, &vel_wrt_joint_w),
                    ],
                );

                // JDot (but the 2.0 originates from the sum of two identical terms in JDot and JDot/u * gdot)
                if !link.joint.kinematic {
                    let mut tmp1 = SMatrix::<Real, SPATIAL_DIM, SPATIAL_DIM>::zeros();
                    let mut rb_joint_j = tmp1.columns_mut(0, ndofs);
                    link.joint.jacobian(
                        &(parent_link.local_to_world.rotation
                            * link.joint.data.local_frame1.rotation),
                        &mut rb_joint_j,
                    );
                    // The link's own dofs are its last columns.
                    let (w2, w1) = (scaled(2.0, &parent_w), scaled(1.0, &parent_w));
                    for d in 0..ndofs {
                        let a = width - ndofs + d;
                        let (block, lane) = (a / LANES, a % LANES);
                        for (w, row0) in [(&w2, 0), (&w1, DIM)] {
                            for k in 0..3 {
                                for (r, wr) in w.iter().enumerate() {
                                    let y =
                                        &mut cor[(block * SPATIAL_DIM + row0 + r) * LANES + lane];
                                    *y = wr[k] * rb_joint_j[(row0 + k, d)] + *y;
                                }
                            }
                        }
                    }
                }
            }

            // [c3 - c2].gcross() * (JDot + JDot/u * qdot)
            let shift_cross_tr = vect_to_na(link.shift23).gcross_matrix_tr();
            // JDot
            let dvel_cross = vect_to_na(rb.vels.angvel.gcross(link.shift23)).gcross_matrix_tr();
            // JDot/u * qdot
            let w_shift =
                SimdAngVector::<Real>::from(rb.vels.angvel).gcross_matrix() * shift_cross_tr;

            /*
             * Meld with the mass matrix.
             */
            let rb_mass_dt = rb_mass * dt;
            let mut icd = core::mem::take(&mut self.workspace.coriolis_dt);
            // Every entry is written by `coriolis_meld`.
            icd.resize(cor.len(), 0.0);
            coriolis_meld(
                &mut cor,
                &jt[i],
                &[
                    scaled(1.0, &shift_cross_tr),
                    scaled(1.0, &dvel_cross),
                    scaled(1.0, &w_shift),
                ],
                [rb_mass_dt.x, rb_mass_dt.y, rb_mass_dt.z],
                &scaled(dt, &mat_to_na(rb_inertia)),
                &mut icd,
            );
            coriolis[i] = cor;

            // `Jᵀ M J` into the mass matrix, `Jᵀ M' J` then `Jᵀ (I C dt)` into the one with
            // the gyroscopic and Coriolis terms, in one pass over `J`.
            transposed_products_add(
                [
                    self.augmented_mass.as_mut_slice(),
                    self.acc_augmented_mass.as_mut_slice(),
                ],
                ld,
                &jt[i],
                [work.as_slice(), acc_work.as_slice()],
                &icd,
                ranges,
            );
            self.workspace.coriolis_dt = icd;
        }
        self.workspace.col_ranges = col_ranges;
        self.workspace.mass_work = [work, acc_work];
        self.workspace.jacobian_blocks = jt;
        self.workspace.coriolis = coriolis;

        /*
         * Damping and armature.
         *
         * Damping is a velocity-proportional force made implicit, so it adds
         * `dt · d` to the mass-matrix diagonal. Armature is a "reflected
         * rotor inertia" (additional inertia to account for the joint’s
         * mass and geometry itself): it adds to the diagonal directly.
         */
        for i in 0..self.ndofs {
            let diag = self.damping[i] * dt + self.armature[i];
            self.acc_augmented_mass[(i, i)] += diag;
            self.augmented_mass[(i, i)] += diag;
        }

        // Implicit joint springs: `dt²·k` on the mass-matrix diagonal (force term in `update_acceleration`)
        // keeps a stiff spring on a low-inertia link stable where an explicit position motor injects energy.
        // The spring lives on the link's `MultibodyJoint` so it travels with the link through topology changes.
        let dt2 = dt * dt;
        for li in 0..self.links.len() {
            let mut idx = self.links[li].assembly_id;
            let locked = self.links[li].joint.data.locked_axes.bits();
            for a in 0..SPATIAL_DIM {
                if (locked >> a) & 1 == 0 {
                    let k = self.links[li].joint.spring_stiffness[a];
                    if k != 0.0 {
                        let d = k * dt2;
                        self.acc_augmented_mass[(idx, idx)] += d;
                        self.augmented_mass[(idx, idx)] += d;
                    }
                    idx += 1;
                }
            }
        }

        let effective_dim = self
            .augmented_mass_indices
            .dim_after_removal(self.acc_augmented_mass.nrows());

        // PERF: since we clone the matrix anyway for LU, should be directly output
        //       a new matrix instead of applying permutations?
        self.augmented_mass_indices
            .rearrange_columns(&mut self.acc_augmented_mass, true);
        self.augmented_mass_indices
            .rearrange_columns(&mut self.augmented_mass, true);

        self.augmented_mass_indices
            .rearrange_rows(&mut self.acc_augmented_mass, true);
        self.augmented_mass_indices
            .rearrange_rows(&mut self.augmented_mass, true);

        // Strider patch: factorised along the tree into the factors' own buffers
        // (`MassFactor`), but for a multibody with kinematic dofs, whose leading blocks
        // nalgebra's LU factorises as upstream.
        if effective_dim == self.ndofs {
            let col_ranges = &self.workspace.col_ranges;
            let dofs = || {
                self.links
                    .iter()
                    .map(|link| (link.assembly_id, link.joint.ndofs()))
            };
            self.acc_inv_augmented_mass
                .set_tree(&self.acc_augmented_mass, col_ranges, dofs());
            self.inv_augmented_mass
                .set_tree_as(&self.augmented_mass, &self.acc_inv_augmented_mass);
        } else {
            let leading =
                |m: &DMatrix<Real>| m.view((0, 0), (effective_dim, effective_dim)).into_owned();
            self.acc_inv_augmented_mass
                .set_dense(leading(&self.acc_augmented_mass));
            self.inv_augmented_mass
                .set_dense(leading(&self.augmented_mass));
        }
    }

    /// Per-DoF inverse joint-space inertia `diag(M⁻¹)` at the current configuration, where `M`
    /// includes armature but excludes joint damping and springs — MuJoCo's `dof_invweight0`: the
    /// apparent inverse inertia at each DoF with all other DoFs free, including the articulated
    /// coupling. Re-runs forward kinematics and reassembles the mass matrix, so intended for
    /// occasional use (e.g. sizing `<joint springdamper>` springs at load time), not every step.
    pub fn dof_inverse_inertia(&mut self, bodies: &RigidBodySet) -> DVector {
        // Resolve the root joint type (a fixed base may still be a 6-DoF free root pre-collapse)
        // so `ndofs` is final, then assemble `M`. `dt = 0` drops the `dt·damping` and
        // `dt²·stiffness` diagonal terms, leaving exactly `M + armature`.
        self.forward_kinematics(bodies, false);
        self.update_mass_matrix(0.0, bodies);

        let n = self.ndofs;
        let mut out = DVector::zeros(n);
        if n == 0 {
            return out;
        }
        // `(M⁻¹)[i, i]` for each DoF: solve `M x = e_i` and read `x[i]`. The `inv_augmented_mass`
        // factorization lives in the kinematic-reduced ordering, so route the unit vector through
        // the same rearrangement the solver uses.
        let mut e = DVector::zeros(n);
        for i in 0..n {
            e.fill(0.0);
            e[i] = 1.0;
            self.augmented_mass_indices
                .with_rearranged_rows_mut(&mut e, |b| {
                    self.inv_augmented_mass.solve_mut(b);
                });
            out[i] = e[i];
        }
        out
    }

    /// Adds a holonomic coupling between two of this multibody's generalized
    /// coordinates (`q2 = coeff·q1 + offset`), enforced as a velocity-level
    /// equality constraint each step. See [`MultibodyDofCoupling`].
    pub fn add_dof_coupling(&mut self, coupling: MultibodyDofCoupling) {
        self.couplings.push(coupling);
    }

    /// The DoF couplings declared on this multibody.
    ///
    /// Couplings follow the multibody's topology changes (link insertions, merges and splits);
    /// a coupling is dropped once one of its DoFs no longer exists, or when its two DoFs end up
    /// in different multibodies.
    pub fn couplings(&self) -> &[MultibodyDofCoupling] {
        &self.couplings
    }

    /// Removes the `i`-th DoF coupling (in the order of [`Self::couplings`]) and returns it.
    ///
    /// Returns `None` if there is no such coupling. The couplings after it shift down by one.
    pub fn remove_dof_coupling(&mut self, i: usize) -> Option<MultibodyDofCoupling> {
        (i < self.couplings.len()).then(|| self.couplings.remove(i))
    }

    /// Keeps only the DoF couplings for which `f` returns `true`.
    pub fn retain_dof_couplings(&mut self, f: impl FnMut(&MultibodyDofCoupling) -> bool) {
        self.couplings.retain(f);
    }

    /// Removes all the DoF couplings of this multibody.
    pub fn clear_dof_couplings(&mut self) {
        self.couplings.clear();
    }

    /// The number of dry-friction rows `link_id`'s joint will emit: one per
    /// free DoF whose `frictionloss` entry is non-zero.
    pub(crate) fn num_friction_constraints(&self, link_id: usize) -> usize {
        let Some(link) = self.link(link_id) else {
            return 0;
        };
        let ndofs = link.joint().ndofs();
        (0..ndofs)
            .filter(|i| self.frictions[link.assembly_id + i] > 0.0)
            .count()
    }

    /// Number of coupling constraints "owned" by `owner_link` — couplings whose first joint
    /// (`link1`) is that link. Each coupling is generated once, by `link1` (which always has a
    /// free DoF and so is an active link in the solver island, unlike a possibly-fixed root).
    pub(crate) fn num_couplings_owned_by(&self, owner_link: usize) -> usize {
        self.couplings
            .iter()
            .filter(|c| c.link1 == owner_link)
            .count()
    }

    /// Generates the velocity constraints for the DoF couplings owned by `owner_link` into
    /// `out[..]`: each coupling `q2 = coeff·q1 + offset` is one bilateral constraint with jacobian
    /// `J = e_{q2} − coeff·e_{q1}` and a rhs pulling the position drift back to zero.
    pub(crate) fn coupling_velocity_constraints(
        &self,
        owner_link: usize,
        params: &IntegrationParameters,
        mut j_id: usize,
        jacobians: &mut DVector,
        out: &mut [GenericJointConstraint],
    ) -> usize {
        let ndofs = self.ndofs;
        let erp_inv_dt = SpringCoefficients::<Real>::joint_defaults().erp_inv_dt(params.dt);

        let mut i = 0;
        for c in self.couplings.iter().filter(|c| c.link1 == owner_link) {
            let g1 = self.links[c.link1].assembly_id + c.dof1;
            let g2 = self.links[c.link2].assembly_id + c.dof2;
            let q1 = self.links[c.link1].joint().coords()[c.axis1];
            let q2 = self.links[c.link2].joint().coords()[c.axis2];

            // Jacobian J = e_{g2} − coeff·e_{g1}, then WJ = M⁻¹ J.
            jacobians.rows_mut(j_id, ndofs * 2).fill(0.0);
            jacobians[j_id + g2] += 1.0;
            jacobians[j_id + g1] -= c.coeff;
            for k in 0..ndofs {
                jacobians[j_id + ndofs + k] = jacobians[j_id + k];
            }
            self.inv_augmented_mass
                .solve_mut(&mut jacobians.rows_mut(j_id + ndofs, ndofs));

            // lhs = Jᵀ M⁻¹ J = Σ J[k]·WJ[k]; only g1/g2 entries of J are nonzero.
            let lhs = jacobians[j_id + ndofs + g2] - c.coeff * jacobians[j_id + ndofs + g1];

            let drift = q2 - c.coeff * q1 - c.offset;

            out[i] = GenericJointConstraint {
                is_rigid_body1: false,
                solver_vel1: u32::MAX,
                ndofs1: 0,
                j_id1: 0,
                is_rigid_body2: false,
                solver_vel2: self.solver_id,
                ndofs2: ndofs,
                j_id2: j_id,
                joint_id: usize::MAX, // internal: no impulse writeback.
                impulse: 0.0,
                impulse_bounds: [-Real::MAX, Real::MAX],
                inv_lhs: crate::utils::inv(lhs),
                rhs: drift * erp_inv_dt,
                rhs_wo_bias: 0.0,
                cfm_coeff: 0.0,
                cfm_gain: 0.0,
                writeback_id: WritebackId::Dof(0),
            };

            j_id += 2 * ndofs;
            i += 1;
        }

        i
    }

    /// The generalized velocity at the multibody_joint of the given link.
    #[inline]
    pub fn joint_velocity(&self, link: &MultibodyLink) -> DVectorView<'_, Real> {
        let ndofs = link.joint().ndofs();
        DVectorView::from_slice(
            &self.velocities.as_slice()[link.assembly_id..link.assembly_id + ndofs],
            ndofs,
        )
    }

    /// The generalized accelerations of this multibodies.
    #[inline]
    pub fn generalized_acceleration(&self) -> DVectorView<'_, Real> {
        self.accelerations.rows(0, self.ndofs)
    }

    /// The generalized velocities of this multibodies.
    #[inline]
    pub fn generalized_velocity(&self) -> DVectorView<'_, Real> {
        self.velocities.rows(0, self.ndofs)
    }

    /// The body jacobian for link `link_id` calculated by the last call to [`Multibody::forward_kinematics`].
    #[inline]
    pub fn body_jacobian(&self, link_id: usize) -> &Jacobian<Real> {
        &self.body_jacobians[link_id]
    }

    /// The mutable generalized velocities of this multibodies.
    #[inline]
    pub fn generalized_velocity_mut(&mut self) -> DVectorViewMut<'_, Real> {
        self.velocities.rows_mut(0, self.ndofs)
    }

    #[inline]
    pub(crate) fn integrate(&mut self, dt: Real) {
        for rb in self.links.iter_mut() {
            rb.joint
                .integrate(dt, &self.velocities.as_slice()[rb.assembly_id..])
        }
    }

    /// Apply displacements, in generalized coordinates, to this multibody.
    ///
    /// Note this does **not** updates the link poses, only their generalized coordinates.
    /// To update the link poses and associated rigid-bodies, call [`Self::forward_kinematics`].
    pub fn apply_displacements(&mut self, disp: &[Real]) {
        for link in self.links.iter_mut() {
            link.joint.apply_displacement(&disp[link.assembly_id..])
        }
    }

    /// Strider patch: writes everything [`Self::forward_kinematics`] reads after
    /// `update_root_type` (the dofs, every link's place in the tree, its joint's
    /// coordinates, rotation, frames and locked axes, its rigid body, that body's type
    /// and centre of mass) to the workspace, and says whether it is bit for bit what the
    /// last call read (`kinematics_inputs`). The links' poses, shifts and body Jacobians
    /// are a function of these alone.
    fn kinematics_inputs_unchanged(&mut self, bodies: &RigidBodySet) -> bool {
        fn reals<const N: usize>(bits: &mut Vec<u32>, values: [Real; N]) {
            bits.extend_from_slice(&values.map(Real::to_bits));
        }
        fn pose(bits: &mut Vec<u32>, pose: &Pose) {
            reals(bits, pose.rotation.to_array());
            reals(bits, pose.translation.to_array());
        }
        // Written whole, then compared as one slice: cheaper than comparing word by word.
        let mut bits = core::mem::take(&mut self.workspace.kinematics_inputs);
        bits.clear();
        bits.extend_from_slice(&[
            self.ndofs as u32,
            self.root_is_dynamic as u32,
            self.links.len() as u32,
        ]);
        for link in self.links.iter() {
            let (index, generation) = link.rigid_body.into_raw_parts();
            let joint = &link.joint;
            bits.extend_from_slice(&[
                link.parent_internal_id as u32,
                link.assembly_id as u32,
                index,
                generation,
                joint.data.locked_axes.bits() as u32,
            ]);
            reals(&mut bits, joint.coords);
            reals(&mut bits, joint.joint_rot.to_array());
            pose(&mut bits, &joint.data.local_frame1);
            pose(&mut bits, &joint.data.local_frame2);
            match bodies.get(link.rigid_body) {
                Some(rb) => {
                    bits.push(rb.body_type as u32);
                    reals(&mut bits, rb.mprops.local_mprops.local_com.to_array());
                }
                None => bits.push(u32::MAX),
            }
        }
        let same = bits == self.kinematics_inputs;
        self.workspace.kinematics_inputs = bits;
        same
    }

    pub(crate) fn update_root_type(&mut self, bodies: &RigidBodySet, take_body_pose: bool) {
        if let Some(rb) = bodies.get(self.links[0].rigid_body) {
            if rb.is_dynamic() != self.root_is_dynamic {
                let root_pose = if take_body_pose {
                    *rb.position()
                } else {
                    self.links[0].local_to_world
                };

                if rb.is_dynamic() {
                    let free_joint = MultibodyJoint::free(root_pose);
                    let prev_root_ndofs = self.links[0].joint().ndofs();
                    self.links[0].joint = free_joint;
                    self.links[0].assembly_id = 0;
                    self.ndofs += SPATIAL_DIM;

                    self.velocities = self.velocities.clone().insert_rows(0, SPATIAL_DIM, 0.0);
                    self.damping = self.damping.clone().insert_rows(0, SPATIAL_DIM, 0.0);
                    self.armature = self.armature.clone().insert_rows(0, SPATIAL_DIM, 0.0);
                    self.frictions = self.frictions.clone().insert_rows(0, SPATIAL_DIM, 0.0);
                    self.accelerations =
                        self.accelerations.clone().insert_rows(0, SPATIAL_DIM, 0.0);

                    for link in &mut self.links[1..] {
                        link.assembly_id += SPATIAL_DIM - prev_root_ndofs;
                    }
                } else {
                    assert!(self.velocities.len() >= SPATIAL_DIM);
                    assert!(self.damping.len() >= SPATIAL_DIM);
                    assert!(self.armature.len() >= SPATIAL_DIM);
                    assert!(self.frictions.len() >= SPATIAL_DIM);
                    assert!(self.accelerations.len() >= SPATIAL_DIM);

                    let fixed_joint = MultibodyJoint::fixed(root_pose);
                    let prev_root_ndofs = self.links[0].joint().ndofs();
                    self.links[0].joint = fixed_joint;
                    self.links[0].assembly_id = 0;
                    self.ndofs -= prev_root_ndofs;

                    if self.ndofs == 0 {
                        self.velocities = DVector::zeros(0);
                        self.damping = DVector::zeros(0);
                        self.armature = DVector::zeros(0);
                        self.frictions = DVector::zeros(0);
                        self.accelerations = DVector::zeros(0);
                    } else {
                        self.velocities =
                            self.velocities.index((prev_root_ndofs.., 0)).into_owned();
                        self.damping = self.damping.index((prev_root_ndofs.., 0)).into_owned();
                        self.armature = self.armature.index((prev_root_ndofs.., 0)).into_owned();
                        self.frictions = self.frictions.index((prev_root_ndofs.., 0)).into_owned();
                        self.accelerations = self
                            .accelerations
                            .index((prev_root_ndofs.., 0))
                            .into_owned();
                    }

                    for link in &mut self.links[1..] {
                        link.assembly_id -= prev_root_ndofs;
                    }
                }

                self.root_is_dynamic = rb.is_dynamic();
            }

            // Make sure the positions are properly set to match the rigid-body’s.
            if take_body_pose {
                if self.links[0].joint.data.locked_axes.is_empty() {
                    self.links[0].joint.set_free_pos(*rb.position());
                } else {
                    self.links[0].joint.data.local_frame1 = *rb.position();
                }
            }
        }
    }

    /// Update the rigid-body poses based on this multibody joint poses.
    ///
    /// This is typically called after [`Self::forward_kinematics`] to apply the new joint poses
    /// to the rigid-bodies.
    pub fn update_rigid_bodies(&self, bodies: &mut RigidBodySet, update_mass_properties: bool) {
        self.update_rigid_bodies_internal(bodies, update_mass_properties, false, true)
    }

    pub(crate) fn update_rigid_bodies_internal(
        &self,
        bodies: &mut RigidBodySet,
        update_mass_properties: bool,
        update_next_positions_only: bool,
        change_tracking: bool,
    ) {
        // Handle the children. They all have a parent within this multibody.
        for link in self.links.iter() {
            let rb = if change_tracking {
                bodies.get_mut_internal_with_modification_tracking(link.rigid_body)
            } else {
                bodies.get_mut_internal(link.rigid_body)
            };

            if let Some(rb) = rb {
                rb.pos.next_position = link.local_to_world;

                if !update_next_positions_only {
                    rb.pos.position = link.local_to_world;
                }

                if update_mass_properties {
                    rb.mprops
                        .update_world_mass_properties(rb.body_type, &link.local_to_world);
                }
            }
        }
    }

    // TODO: make a version that doesn’t write back to bodies and doesn’t update the jacobians
    //       (i.e. just something used by the velocity solver’s small steps).
    /// Apply forward-kinematics to this multibody.
    ///
    /// This will update the [`MultibodyLink`] pose information as wall as the body jacobians.
    /// This will also ensure that the multibody has the proper number of degrees of freedom if
    /// its root node changed between dynamic and non-dynamic.
    ///
    /// Note that this does **not** update the poses of the [`RigidBody`] attached to the joints.
    /// Run [`Self::update_rigid_bodies`] to trigger that update.
    ///
    /// This method updates `self` with the result of the forward-kinematics operation.
    /// For a non-mutable version running forward kinematics on a single link, see
    /// [`Self::forward_kinematics_single_link`].
    ///
    /// ## Parameters
    /// - `bodies`: the set of rigid-bodies.
    /// - `read_root_pose_from_rigid_body`: if set to `true`, the root joint (either a fixed joint,
    ///   or a free joint) will have its pose set to its associated-rigid-body pose. Set this to `true`
    ///   when the root rigid-body pose has been modified and needs to affect the multibody.
    pub fn forward_kinematics(
        &mut self,
        bodies: &RigidBodySet,
        read_root_pose_from_rigid_body: bool,
    ) {
        // Be sure the degrees of freedom match and take the root position if needed.
        self.update_root_type(bodies, read_root_pose_from_rigid_body);

        // Strider patch: the pipeline runs forward kinematics at the start of every step
        // (for changes the user made between steps) and again after integrating the
        // positions at its end; with nothing changed between, the first reads the bits
        // the second read and computes the bits it left (half of forward kinematics' 10 %
        // of a late search's step; skipping it, record included, saves about 3.5 %).
        if self.kinematics_inputs_unchanged(bodies) {
            return;
        }

        // Special case for the root, which has no parent.
        {
            let link = &mut self.links[0];
            link.local_to_parent = link.joint.body_to_parent();
            link.local_to_world = link.local_to_parent;
        }

        // Handle the children. They all have a parent within this multibody.
        for i in 1..self.links.len() {
            let (link, parent_link) = self.links.get_mut_with_parent(i);

            link.local_to_parent = link.joint.body_to_parent();
            link.local_to_world = parent_link.local_to_world * link.local_to_parent;

            {
                let parent_rb = &bodies[parent_link.rigid_body];
                let link_rb = &bodies[link.rigid_body];
                let c0 = parent_link.local_to_world * parent_rb.mprops.local_mprops.local_com;
                let c2 = link.local_to_world * link.joint.data.local_frame2.translation;
                let c3 = link.local_to_world * link_rb.mprops.local_mprops.local_com;

                link.shift02 = c2 - c0;
                link.shift23 = c3 - c2;
            }

            assert_eq!(
                bodies[link.rigid_body].body_type,
                RigidBodyType::Dynamic,
                "A rigid-body that is not at the root of a multibody must be dynamic."
            );
        }

        /*
         * Compute body jacobians.
         */
        self.update_body_jacobians();

        // Strider patch: what was read, kept once its outputs are all computed (a call
        // that panicked leaves none that a later call could take as computed).
        core::mem::swap(
            &mut self.kinematics_inputs,
            &mut self.workspace.kinematics_inputs,
        );
    }

    /// Computes the ids of all the links between the root and the link identified by `link_id`.
    pub fn kinematic_branch(&self, link_id: usize) -> Vec<usize> {
        let mut branch = vec![]; // Perf: avoid allocation.
        let mut curr_id = Some(link_id);

        while let Some(id) = curr_id {
            branch.push(id);
            curr_id = self.links[id].parent_id();
        }

        branch.reverse();
        branch
    }

    /// Apply forward-kinematics to compute the position of a single link of this multibody.
    ///
    /// If `out_jacobian` is `Some`, this will simultaneously compute the new jacobian of this link.
    /// If `displacement` is `Some`, the generalized position considered during transform propagation
    /// is the sum of the current position of `self` and this `displacement`.
    // TODO: this shares a lot of code with `forward_kinematics` and `update_body_jacobians`, except
    //       that we are only traversing a single kinematic chain. Could this be refactored?
    pub fn forward_kinematics_single_link(
        &self,
        bodies: &RigidBodySet,
        link_id: usize,
        displacement: Option<&[Real]>,
        out_jacobian: Option<&mut Jacobian<Real>>,
    ) -> Pose {
        let branch = self.kinematic_branch(link_id);
        self.forward_kinematics_single_branch(bodies, &branch, displacement, out_jacobian)
    }

    /// Apply forward-kinematics to compute the position of a single sorted branch of this multibody.
    ///
    /// The given `branch` must have the following properties:
    /// - It must be sorted, i.e., `branch[i] < branch[i + 1]`.
    /// - All the indices must be part of the same kinematic branch.
    /// - If a link is `branch[i]`, then `branch[i - 1]` must be its parent.
    ///
    /// In general, this method shouldn’t be used directly and [`Self::forward_kinematics_single_link`]
    /// should be preferred since it computes the branch indices automatically.
    ///
    /// If you want to calculate the branch indices manually, see [`Self::kinematic_branch`].
    ///
    /// If `out_jacobian` is `Some`, this will simultaneously compute the new jacobian of this branch.
    /// This represents the body jacobian for the last link in the branch.
    ///
    /// If `displacement` is `Some`, the generalized position considered during transform propagation
    /// is the sum of the current position of `self` and this `displacement`.
    // TODO: this shares a lot of code with `forward_kinematics` and `update_body_jacobians`, except
    //       that we are only traversing a single kinematic chain. Could this be refactored?
    #[profiling::function]
    pub fn forward_kinematics_single_branch(
        &self,
        bodies: &RigidBodySet,
        branch: &[usize],
        displacement: Option<&[Real]>,
        mut out_jacobian: Option<&mut Jacobian<Real>>,
    ) -> Pose {
        if let Some(out_jacobian) = out_jacobian.as_deref_mut() {
            if out_jacobian.ncols() != self.ndofs {
                *out_jacobian = Jacobian::zeros(self.ndofs);
            } else {
                out_jacobian.fill(0.0);
            }
        }

        let mut parent_link: Option<MultibodyLink> = None;

        for i in branch {
            let mut link = self.links[*i];

            if let Some(displacement) = displacement {
                link.joint
                    .apply_displacement(&displacement[link.assembly_id..]);
            }

            let parent_to_world;

            if let Some(parent_link) = parent_link {
                link.local_to_parent = link.joint.body_to_parent();
                link.local_to_world = parent_link.local_to_world * link.local_to_parent;

                {
                    let parent_rb = &bodies[parent_link.rigid_body];
                    let link_rb = &bodies[link.rigid_body];
                    let c0 = parent_link.local_to_world * parent_rb.mprops.local_mprops.local_com;
                    let c2 = link.local_to_world
                        * Vector::from(link.joint.data.local_frame2.translation);
                    let c3 = link.local_to_world * link_rb.mprops.local_mprops.local_com;

                    link.shift02 = c2 - c0;
                    link.shift23 = c3 - c2;
                }

                parent_to_world = parent_link.local_to_world;

                if let Some(out_jacobian) = out_jacobian.as_deref_mut() {
                    let (mut link_j_v, parent_j_w) =
                        out_jacobian.rows_range_pair_mut(0..DIM, DIM..DIM + ANG_DIM);
                    let shift_tr = vect_to_na(link.shift02).gcross_matrix_tr();
                    link_j_v.gemm(1.0, &shift_tr, &parent_j_w, 1.0);
                }
            } else {
                link.local_to_parent = link.joint.body_to_parent();
                link.local_to_world = link.local_to_parent;
                parent_to_world = Pose::IDENTITY;
            }

            if let Some(out_jacobian) = out_jacobian.as_deref_mut() {
                let ndofs = link.joint.ndofs();
                let mut tmp = SMatrix::<Real, SPATIAL_DIM, SPATIAL_DIM>::zeros();
                let mut link_joint_j = tmp.columns_mut(0, ndofs);
                let mut link_j_part = out_jacobian.columns_mut(link.assembly_id, ndofs);
                link.joint.jacobian(
                    &(parent_to_world.rotation * link.joint.data.local_frame1.rotation),
                    &mut link_joint_j,
                );
                link_j_part += link_joint_j;

                {
                    let (mut link_j_v, link_j_w) =
                        out_jacobian.rows_range_pair_mut(0..DIM, DIM..DIM + ANG_DIM);
                    let shift_tr = vect_to_na(link.shift23).gcross_matrix_tr();
                    link_j_v.gemm(1.0, &shift_tr, &link_j_w, 1.0);
                }
            }

            parent_link = Some(link);
        }

        parent_link
            .map(|link| link.local_to_world)
            .unwrap_or(Pose::IDENTITY)
    }

    /// The total number of freedoms of this multibody.
    #[inline]
    pub fn ndofs(&self) -> usize {
        self.ndofs
    }

    pub(crate) fn fill_jacobians(
        &self,
        link_id: usize,
        unit_force: Vector,
        unit_torque: AngVector,
        j_id: &mut usize,
        jacobians: &mut DVector,
    ) -> (Real, Real) {
        if self.ndofs == 0 {
            return (0.0, 0.0);
        }

        let wj_id = *j_id + self.ndofs;
        let force = Force {
            linear: unit_force,
            #[cfg(feature = "dim2")]
            angular: unit_torque,
            #[cfg(feature = "dim3")]
            angular: unit_torque,
        };

        let link = &self.links[link_id];
        let mut out_j = jacobians.rows_mut(*j_id, self.ndofs);
        self.body_jacobians[link.internal_id].tr_mul_to(force.as_vector(), &mut out_j);

        // TODO: Optimize with a copy_nonoverlapping?
        for i in 0..self.ndofs {
            jacobians[wj_id + i] = jacobians[*j_id + i];
        }

        {
            let mut out_invm_j = jacobians.rows_mut(wj_id, self.ndofs);
            self.augmented_mass_indices
                .with_rearranged_rows_mut(&mut out_invm_j, |out_invm_j| {
                    self.inv_augmented_mass.solve_mut(out_invm_j);
                });
        }

        let j = jacobians.rows(*j_id, self.ndofs);
        let invm_j = jacobians.rows(wj_id, self.ndofs);
        *j_id += self.ndofs * 2;

        (j.dot(&invm_j), j.dot(&self.generalized_velocity()))
    }

    /// Strider patch: [`Self::fill_jacobians`] without its solve: writes the row's
    /// Jacobian `J` at `j_id` and a copy of it after, for [`Self::solve_jacobians`] to turn
    /// into `M⁻¹ Jᵀ` together with the other rows of a contact; then
    /// [`Self::jacobian_dot`] gives what `fill_jacobians` returns first.
    pub(crate) fn fill_jacobians_unsolved(
        &self,
        link_id: usize,
        unit_force: Vector,
        unit_torque: AngVector,
        j_id: &mut usize,
        jacobians: &mut DVector,
    ) {
        if self.ndofs == 0 {
            return;
        }
        let force = Force {
            linear: unit_force,
            angular: unit_torque,
        };
        let link = &self.links[link_id];
        let body_jacobian = &self.body_jacobians[link.internal_id];
        let (j, n) = (*j_id, self.ndofs);
        // Strider patch: the body Jacobian is zero outside the columns of the link's own
        // and its ancestors' dofs (`link_column_ranges`, kept by `update_mass_matrix`,
        // which runs before any constraint of the step is built), and there upstream's
        // `tr_mul_to` wrote a dot product of a zero column with a finite wrench: +0, as
        // written here; inside, each entry is that dot product (docs/rapier.md,
        // "Mass-matrix sparsity").
        match self.workspace.col_ranges.get(link.internal_id) {
            Some(ranges) if self.workspace.col_ranges.len() == self.links.len() => {
                let out = &mut jacobians.as_mut_slice()[j..j + n];
                out.fill(0.0);
                for &(s, m) in ranges {
                    for c in s..s + m {
                        out[c] = body_jacobian.column(c).dot(force.as_vector());
                    }
                }
                debug_assert!(
                    (0..n)
                        .filter(|c| !ranges.iter().any(|&(s, m)| (s..s + m).contains(c)))
                        .all(|c| body_jacobian.column(c).iter().all(|v| *v == 0.0)),
                    "a link's body Jacobian nonzero outside its column ranges"
                );
            }
            _ => body_jacobian.tr_mul_to(force.as_vector(), &mut jacobians.rows_mut(j, n)),
        }
        jacobians.as_mut_slice().copy_within(j..j + n, j + n);
        *j_id += self.ndofs * 2;
    }

    /// Strider patch: `J · M⁻¹ Jᵀ` of the row at `j_id`, once solved (0 for no dofs, as
    /// [`Self::fill_jacobians`] gives).
    pub(crate) fn jacobian_dot(&self, j_id: usize, jacobians: &DVector) -> Real {
        if self.ndofs == 0 {
            return 0.0;
        }
        let j = jacobians.rows(j_id, self.ndofs);
        let invm_j = jacobians.rows(j_id + self.ndofs, self.ndofs);
        j.dot(&invm_j)
    }

    /// Strider patch: the solve of [`Self::fill_jacobians`] for several rows at once (the
    /// rows [`Self::fill_jacobians_unsolved`] wrote at `j_ids`).
    ///
    /// A solve of one row is a chain whose every step waits on the one before; a
    /// contact's rows (up to 12) are independent, so here they are solved side by side
    /// ([`MassFactor::solve_rows`]), each entry of each row receiving exactly the
    /// operations, in the same order, that [`MassFactor::solve_mut`] gives it: the same
    /// bits, without the wait. Rows of a multibody whose matrix nalgebra's LU factorised
    /// (kinematic dofs, a pivot that was not positive), or more rows or dofs than the
    /// buffer holds, are solved one by one.
    pub(crate) fn solve_jacobians(&self, j_ids: &[usize], jacobians: &mut DVector) {
        const MAX_ROWS: usize = 3 * crate::math::MAX_MANIFOLD_POINTS;
        const MAX_DOFS: usize = mass_factor::MAX_DOFS;
        let n = self.ndofs;
        let rows = j_ids.len();
        let batched = self.augmented_mass_indices.first_to_remove == IndexSequence::NONE
            && (2..=MAX_ROWS).contains(&rows)
            && (1..=MAX_DOFS).contains(&n)
            && self.inv_augmented_mass.is_tree()
            && self.inv_augmented_mass.nrows() == n;
        if !batched {
            if n == 0 {
                return;
            }
            for &j_id in j_ids {
                let mut out_invm_j = jacobians.rows_mut(j_id + n, n);
                self.augmented_mass_indices.with_rearranged_rows_mut(
                    &mut out_invm_j,
                    |out_invm_j| {
                        self.inv_augmented_mass.solve_mut(out_invm_j);
                    },
                );
            }
            return;
        }
        // Row-interleaved: entry i of row c at `x[i][c]`, `MAX_ROWS` wide whatever the
        // number of rows (the unused lanes hold zeros and are dropped), so that every
        // loop is a fixed-length one the compiler turns into vector instructions.
        // Only the `n` rows in use are zeroed (the whole buffer is 3 kB, and a contact's
        // rows are solved every step).
        let mut buffer = [const { core::mem::MaybeUninit::<[Real; MAX_ROWS]>::uninit() }; MAX_DOFS];
        for row in &mut buffer[..n] {
            row.write([0.0; MAX_ROWS]);
        }
        // SAFETY: the first `n` rows were written just above (`n <= MAX_DOFS`: `batched`),
        // and `MaybeUninit<T>` has `T`'s layout.
        let x = unsafe {
            &mut *core::ptr::slice_from_raw_parts_mut(
                buffer.as_mut_ptr().cast::<[Real; MAX_ROWS]>(),
                n,
            )
        };
        for (c, &j_id) in j_ids.iter().enumerate() {
            let row = &jacobians.as_slice()[j_id + n..j_id + 2 * n];
            for (xi, v) in x.iter_mut().zip(row) {
                xi[c] = *v;
            }
        }
        let solved = solve_rows(&self.inv_augmented_mass, x);
        debug_assert!(solved, "a tree factor of the rows' size");
        for (c, &j_id) in j_ids.iter().enumerate() {
            for (i, xi) in x.iter().enumerate() {
                jacobians[j_id + n + i] = xi[c];
            }
        }
    }

    /// Fills `jacobians` with the relative jacobian `J = J2ᵀ·f2 − J1ᵀ·f1` of two links of `self`, then `M⁻¹·J`
    /// (e.g. a loop closure). The difference must be explicit: per-link blocks lose the `J1ᵀ·W·J2` effective-mass
    /// coupling since both act on the same generalized velocities. Cancellation-vanished rows are zeroed so the solver skips them.
    pub(crate) fn fill_relative_jacobians(
        &self,
        link_id1: usize,
        unit_force1: Vector,
        unit_torque1: AngVector,
        link_id2: usize,
        unit_force2: Vector,
        unit_torque2: AngVector,
        j_id: &mut usize,
        jacobians: &mut DVector,
    ) {
        if self.ndofs == 0 {
            return;
        }

        let wj_id = *j_id + self.ndofs;
        let force1 = Force {
            linear: unit_force1,
            angular: unit_torque1,
        };
        let force2 = Force {
            linear: unit_force2,
            angular: unit_torque2,
        };

        let link1 = &self.links[link_id1];
        let link2 = &self.links[link_id2];

        {
            let jb1 = &self.body_jacobians[link1.internal_id];
            let jb2 = &self.body_jacobians[link2.internal_id];

            // Use the (overwritten below) W·J slot as workspace for J1ᵀ·f1.
            let (mut out_j, mut workspace) =
                jacobians.rows_range_pair_mut(*j_id..*j_id + self.ndofs, wj_id..wj_id + self.ndofs);
            jb2.tr_mul_to(force2.as_vector(), &mut out_j);
            jb1.tr_mul_to(force1.as_vector(), &mut workspace);
            out_j.axpy(-1.0, &workspace, 1.0);

            // Cancellation guard: the reference scale is the magnitude of the dot-product operands,
            // not their results (which may be pure cancellation noise when the direction isn’t
            // expressible by the dofs). Rows below ~1000·ε times that scale are noise, not a constraint.
            let scale_sq = jb1.norm_squared() * force1.as_vector().norm_squared()
                + jb2.norm_squared() * force2.as_vector().norm_squared();
            let eps = Real::EPSILON * 1.0e3;
            if out_j.norm_squared() <= eps * eps * scale_sq {
                out_j.fill(0.0);
            }
        }

        // TODO: Optimize with a copy_nonoverlapping?
        for i in 0..self.ndofs {
            jacobians[wj_id + i] = jacobians[*j_id + i];
        }

        {
            let mut out_invm_j = jacobians.rows_mut(wj_id, self.ndofs);
            self.augmented_mass_indices
                .with_rearranged_rows_mut(&mut out_invm_j, |out_invm_j| {
                    self.inv_augmented_mass.solve_mut(out_invm_j);
                });
        }

        *j_id += self.ndofs * 2;
    }
}

/// Strider patch: `v` as a vector of `n` entries, its contents scratch (zeros when it had
/// to be allocated).
fn scratch_zeros(v: &mut DVector, n: usize) {
    if v.len() != n {
        *v = DVector::zeros(n);
    } else {
        v.as_mut_slice().fill(0.0);
    }
}

/// Strider patch: [`Multibody::free_velocity_energy_guard`]'s test, on the vectors in the
/// factorised matrices' ordering: the energy the implicit solve's accelerations
/// `a` add over the step, less the forces' work and a margin (`None` for a non-finite
/// `a`). Upstream's arithmetic in upstream's order: `m * x` is `gemv` (a product by a
/// one-column matrix is computed by it), here into `products` instead of a new vector.
fn energy_excess_in_place(
    m: na::DMatrixView<Real>,
    v: &DVector,
    f: &DVector,
    f_pos: &DVector,
    a: &DVector,
    dt: Real,
    products: &mut [DVector; 2],
) -> Option<Real> {
    if !a.iter().all(|x| x.is_finite()) {
        return None;
    }
    let [m_a, m_v] = products;
    if m_a.len() != a.len() {
        *m_a = DVector::zeros(a.len());
        *m_v = DVector::zeros(a.len());
    }
    m_a.gemv(1.0, &m, a, 0.0);
    let energy_delta = dt * v.dot(m_a) + 0.5 * dt * dt * a.dot(m_a);
    let work = dt * v.dot(f) + 0.5 * dt * dt * a.dot(f_pos);
    // Margin: a small fraction of the current kinetic energy to absorb
    // discretization error on healthy steps.
    m_v.gemv(1.0, &m, v, 0.0);
    let kinetic_energy = 0.5 * v.dot(m_v);
    let energy_margin = 1.0e-2 * kinetic_energy + 1.0e-8;
    Some(energy_delta - work - energy_margin)
}

#[cfg_attr(feature = "serde-serialize", derive(Serialize, Deserialize))]
#[derive(Clone, Debug)]
struct IndexSequence {
    first_to_remove: u32,
    index_map: Vec<usize>,
}

impl IndexSequence {
    const NONE: u32 = u32::MAX;

    fn new() -> Self {
        Self {
            first_to_remove: Self::NONE,
            index_map: vec![],
        }
    }

    /// Index of the first removed dof, assuming there is one.
    fn start(&self) -> usize {
        self.first_to_remove as usize
    }

    fn clear(&mut self) {
        self.first_to_remove = Self::NONE;
        self.index_map.clear();
    }

    fn keep(&mut self, i: usize) {
        if self.first_to_remove == Self::NONE {
            // Nothing got removed yet. No need to register any
            // special indexing.
            return;
        }

        self.index_map.push(i);
    }

    fn remove(&mut self, i: usize) {
        if self.first_to_remove == Self::NONE {
            self.first_to_remove = i as u32;
        }
    }

    fn dim_after_removal(&self, original_dim: usize) -> usize {
        if self.first_to_remove == Self::NONE {
            original_dim
        } else {
            self.start() + self.index_map.len()
        }
    }

    fn rearrange_columns<R: na::Dim, C: na::Dim, S: StorageMut<Real, R, C>>(
        &self,
        mat: &mut na::Matrix<Real, R, C, S>,
        clear_removed: bool,
    ) {
        if self.first_to_remove == Self::NONE {
            // Nothing to rearrange.
            return;
        }

        for (target_shift, source) in self.index_map.iter().enumerate() {
            let target = self.start() + target_shift;
            let (mut target_col, source_col) = mat.columns_range_pair_mut(target, *source);
            target_col.copy_from(&source_col);
        }

        if clear_removed {
            mat.columns_range_mut(self.start() + self.index_map.len()..)
                .fill(0.0);
        }
    }

    fn rearrange_rows<R: na::Dim, C: na::Dim, S: StorageMut<Real, R, C>>(
        &self,
        mat: &mut na::Matrix<Real, R, C, S>,
        clear_removed: bool,
    ) {
        if self.first_to_remove == Self::NONE {
            // Nothing to rearrange.
            return;
        }

        for mut col in mat.column_iter_mut() {
            for (target_shift, source) in self.index_map.iter().enumerate() {
                let target = self.start() + target_shift;
                col[target] = col[*source];
            }

            if clear_removed {
                col.rows_range_mut(self.start() + self.index_map.len()..)
                    .fill(0.0);
            }
        }
    }

    fn inv_rearrange_rows<R: na::Dim, C: na::Dim, S: StorageMut<Real, R, C>>(
        &self,
        mat: &mut na::Matrix<Real, R, C, S>,
    ) {
        if self.first_to_remove == Self::NONE {
            // Nothing to rearrange.
            return;
        }

        for mut col in mat.column_iter_mut() {
            for (target_shift, source) in self.index_map.iter().enumerate().rev() {
                let target = self.start() + target_shift;
                col[*source] = col[target];
                col[target] = 0.0;
            }
        }
    }

    fn with_rearranged_rows_mut<C: na::Dim, S: StorageMut<Real, Dyn, C>>(
        &self,
        mat: &mut na::Matrix<Real, Dyn, C, S>,
        mut f: impl FnMut(&mut na::MatrixViewMut<Real, Dyn, C, S::RStride, S::CStride>),
    ) {
        self.rearrange_rows(mat, true);
        let effective_dim = self.dim_after_removal(mat.nrows());
        if effective_dim > 0 {
            f(&mut mat.rows_mut(0, effective_dim));
        }
        self.inv_rearrange_rows(mat);
    }
}

/// Strider patch: `out.columns(s, n) = m * j.columns(s, n)`, the spatial mass matrix times
/// a range of a link's body Jacobian, with the same bits on every CPU.
///
/// nalgebra hands this product to the `matrixmultiply` crate when the range has more than 5
/// columns, and that crate picks its kernel by the CPU it runs on: on x86-64 with FMA each
/// entry is a chain of fused multiply-adds over `k` from zero, on older CPUs separate
/// multiplies and adds, so the same binary stepped a robot differently on two kinds of
/// node. Here each entry is always that fused chain, in matrixmultiply's order (bit for bit
/// what its FMA kernels give; the CPU's own FMA where it has one, the C library's exact
/// `fmaf` where not), and without its packing, which cost more than the product for these
/// 6-row blocks. Ranges of 5 columns or fewer keep nalgebra's own loops, as before.
#[inline]
fn spatial_product(
    out: &mut Jacobian<Real>,
    m: &SMatrix<Real, SPATIAL_DIM, SPATIAL_DIM>,
    j: &Jacobian<Real>,
    s: usize,
    n: usize,
) {
    // nalgebra used matrixmultiply when both dimensions of both operands passed 5: in 3D
    // (6 rows) for more than 5 columns, never in 2D (3 rows).
    #[cfg(feature = "std")]
    if SPATIAL_DIM > 5 && n > 5 {
        let (out, m, j) = (out.as_mut_slice(), m.as_slice(), j.as_slice());
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU has AVX and FMA, checked just above.
            unsafe { fused_product_fma(out, m, j, s, n) };
            return;
        }
        fused_product(out, m, j, s, n);
        return;
    }
    out.columns_mut(s, n).gemm(1.0, m, &j.columns(s, n), 0.0);
}

/// [`MassFactor::solve_rows`] for [`Multibody::solve_jacobians`]'s buffer, with AVX's
/// eight lanes where the CPU has it (no FMA, so each entry's arithmetic is unchanged).
fn solve_rows(factor: &MassFactor, x: &mut [[Real; 3 * crate::math::MAX_MANIFOLD_POINTS]]) -> bool {
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    if std::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU has AVX, checked just above.
        return unsafe { solve_rows_avx(factor, x) };
    }
    factor.solve_rows(x)
}

/// [`MassFactor::solve_rows`] compiled for CPUs with AVX.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx")]
unsafe fn solve_rows_avx(
    factor: &MassFactor,
    x: &mut [[Real; 3 * crate::math::MAX_MANIFOLD_POINTS]],
) -> bool {
    factor.solve_rows(x)
}

/// Fills `ranges[i]` with link `i`'s nonzero body-Jacobian columns `(start, len)`: its
/// ancestors' and its own dofs, adjacent runs merged. Links come parents first. Reuses the
/// vectors already there.
pub(crate) fn link_column_ranges(links: &[MultibodyLink], ranges: &mut Vec<Vec<(usize, usize)>>) {
    ranges.resize_with(links.len(), Vec::new);
    for (i, link) in links.iter().enumerate() {
        debug_assert!(
            i == 0 || link.parent_internal_id < i,
            "a child before its parent"
        );
        let own = (link.assembly_id, link.joint.ndofs());
        // A parent comes before its children, so its ranges are already filled.
        let (before, from_i) = ranges.split_at_mut(i);
        let link_ranges = &mut from_i[0];
        if i == 0 {
            link_ranges.clear();
        } else {
            link_ranges.clone_from(&before[link.parent_internal_id]);
        }
        if own.1 > 0 {
            match link_ranges.last_mut() {
                Some(last) if last.0 + last.1 == own.0 => last.1 += own.1,
                _ => link_ranges.push(own),
            }
        }
    }
}

/// `y += Jᵀ w` over the columns `ranges` of `j` (a link's, from [`link_column_ranges`]),
/// each entry by nalgebra's `gemv_tr` as upstream computed it over all columns: outside
/// `ranges` that added `1·(+0)` to an entry that started at +0, which changes nothing.
fn add_transposed_product(
    y: &mut DVector,
    j: &Jacobian<Real>,
    w: &SVector<Real, SPATIAL_DIM>,
    ranges: &[(usize, usize)],
) {
    for &(s, n) in ranges {
        y.rows_mut(s, n).gemv_tr(1.0, &j.columns(s, n), w, 1.0);
    }
}

/// Lanes of [`transposed_products_add`]'s blocks: eight `f32` fill one AVX register.
const LANES: usize = 8;

/// Copies the columns `ranges` of `j`, in order and side by side, into `jt` for
/// [`transposed_products_add`]: blocks of [`LANES`] columns, each block `SPATIAL_DIM` rows of
/// [`LANES`] entries (`jt[(block * SPATIAL_DIM + k) * LANES + lane]`), the last block padded
/// with zeros.
fn transpose_columns(jt: &mut Vec<Real>, j: &Jacobian<Real>, ranges: &[(usize, usize)]) {
    const D: usize = SPATIAL_DIM;
    let m: usize = ranges.iter().map(|r| r.1).sum();
    let blocks = m.div_ceil(LANES);
    jt.clear();
    jt.resize(blocks * D * LANES, 0.0);
    let j = j.as_slice();
    let mut a = 0;
    for &(s, n) in ranges {
        for c in s..s + n {
            let (block, lane) = (a / LANES, a % LANES);
            for k in 0..D {
                jt[(block * D + k) * LANES + lane] = j[c * D + k];
            }
            a += 1;
        }
    }
}

/// For every `a` and `b` in `ranges`: `outs[0][(a, b)] += j[.., a] · ws[0][.., b]`, then
/// `outs[1][(a, b)] += j[.., a] · ws[1][.., b]` and `+= j[.., a] · c[.., b]` (`outs`
/// column-major with `ld` rows; `jt` the columns of `j` from [`transpose_columns`], `ws`
/// column-major `SPATIAL_DIM x ndofs`, `c` in `jt`'s layout). These are the blocks
/// nalgebra's `gemm_tr(1.0, j.columns(..), w.columns(..), 1.0)` gave, with its arithmetic
/// per entry (a dot product summed in row order from +0, unfused, then added to the entry),
/// and in the order upstream added them, so the same bits; laid out so the compiler computes
/// [`LANES`] entries side by side, where nalgebra's dot products went one entry at a time,
/// and `j` read once for the three.
#[inline]
fn transposed_products_add(
    outs: [&mut [Real]; 2],
    ld: usize,
    jt: &[Real],
    ws: [&[Real]; 2],
    c: &[Real],
    ranges: &[(usize, usize)],
) {
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    if std::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU has AVX, checked just above.
        unsafe { transposed_products_add_avx(outs, ld, jt, ws, c, ranges) };
        return;
    }
    transposed_products_add_any(outs, ld, jt, ws, c, ranges, add_dots_any);
}

/// [`transposed_products_add_any`] compiled for CPUs with AVX (no FMA, so each entry's
/// arithmetic is unchanged).
#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx")]
unsafe fn transposed_products_add_avx(
    outs: [&mut [Real]; 2],
    ld: usize,
    jt: &[Real],
    ws: [&[Real]; 2],
    c: &[Real],
    ranges: &[(usize, usize)],
) {
    // SAFETY (of `add_dots_avx`): this function runs only where the CPU has AVX.
    #[cfg(feature = "f32")]
    transposed_products_add_any(outs, ld, jt, ws, c, ranges, |o0, o1, d, r| unsafe {
        add_dots_avx(o0, o1, d, r)
    });
    #[cfg(not(feature = "f32"))]
    transposed_products_add_any(outs, ld, jt, ws, c, ranges, add_dots_any);
}

#[inline(always)]
fn transposed_products_add_any(
    outs: [&mut [Real]; 2],
    ld: usize,
    jt: &[Real],
    ws: [&[Real]; 2],
    c: &[Real],
    ranges: &[(usize, usize)],
    add_dots: impl Fn(&mut [Real], &mut [Real], [&[Real]; 3], &[(usize, usize)]),
) {
    const D: usize = SPATIAL_DIM;
    let [out0, out1] = outs;
    // One output column's entries over `ranges`, side by side, for each of the three
    // products (at most 4 blocks each on the stack: 32 columns, more than any link here
    // has; longer ones take the heap).
    let blocks = jt.len() / (D * LANES);
    let mut stack = [[0.0 as Real; LANES]; 12];
    let mut heap = Vec::new();
    let dots: &mut [[Real; LANES]] = if 3 * blocks <= stack.len() {
        &mut stack[..3 * blocks]
    } else {
        heap.resize(3 * blocks, [0.0 as Real; LANES]);
        &mut heap
    };
    let (dots0, rest) = dots.split_at_mut(blocks);
    let (dots1, dots2) = rest.split_at_mut(blocks);
    let mut bc = 0;
    for &(sb, nb) in ranges {
        for b in sb..sb + nb {
            let w0 = &ws[0][b * D..b * D + D];
            let w1 = &ws[1][b * D..b * D + D];
            let (cblock, clane) = (bc / LANES, bc % LANES);
            let wc: [Real; D] = core::array::from_fn(|k| c[(cblock * D + k) * LANES + clane]);
            bc += 1;
            for block in 0..blocks {
                let rows = &jt[block * D * LANES..(block + 1) * D * LANES];
                let mut acc = [[0.0 as Real; LANES]; 3];
                for k in 0..D {
                    let row = &rows[k * LANES..k * LANES + LANES];
                    for l in 0..LANES {
                        acc[0][l] += row[l] * w0[k];
                        acc[1][l] += row[l] * w1[k];
                        acc[2][l] += row[l] * wc[k];
                    }
                }
                dots0[block] = acc[0];
                dots1[block] = acc[1];
                dots2[block] = acc[2];
            }
            let (flat0, flat1, flat2) = (
                dots0.as_flattened(),
                dots1.as_flattened(),
                dots2.as_flattened(),
            );
            add_dots(
                &mut out0[b * ld..b * ld + ld],
                &mut out1[b * ld..b * ld + ld],
                [flat0, flat1, flat2],
                ranges,
            );
        }
    }
}

/// One output column of [`transposed_products_add`]: for each range `(s, n)` of `ranges`,
/// the next `n` dot products of `dots` (taken in order over the ranges) added to entries
/// `s..s + n`: `out0 += dots[0]`, `out1 = (out1 + dots[1]) + dots[2]`, entry by entry.
#[inline(always)]
fn add_dots_any(
    out0: &mut [Real],
    out1: &mut [Real],
    dots: [&[Real]; 3],
    ranges: &[(usize, usize)],
) {
    let mut a = 0;
    for &(s, n) in ranges {
        let (o0, o1) = (&mut out0[s..s + n], &mut out1[s..s + n]);
        let (d0, d1, d2) = (&dots[0][a..a + n], &dots[1][a..a + n], &dots[2][a..a + n]);
        for t in 0..n {
            o0[t] += d0[t];
            o1[t] = (o1[t] + d1[t]) + d2[t];
        }
        a += n;
    }
}

/// [`add_dots_any`] [`LANES`] entries at a time with AVX's masked loads and stores: the same
/// additions, lane by lane (a range is a few entries, which the compiler's loops did one
/// at a time).
///
/// # Safety
/// The CPU must have AVX.
#[cfg(all(feature = "std", feature = "f32", target_arch = "x86_64"))]
#[target_feature(enable = "avx")]
#[inline]
unsafe fn add_dots_avx(
    out0: &mut [Real],
    out1: &mut [Real],
    dots: [&[Real]; 3],
    ranges: &[(usize, usize)],
) {
    use super::mass_factor::first_lanes;
    use core::arch::x86_64::{_mm256_add_ps, _mm256_maskload_ps, _mm256_maskstore_ps};
    let mut a = 0;
    for &(s, n) in ranges {
        // Checked once, so the pointers below stay inside the slices.
        assert!(s + n <= out0.len() && s + n <= out1.len());
        assert!(a + n <= dots[0].len() && a + n <= dots[1].len() && a + n <= dots[2].len());
        let mut t = 0;
        while t < n {
            let k = (n - t).min(LANES);
            // SAFETY: the CPU has AVX (the caller's contract); each masked load and store
            // touches only the first `k` lanes, entries `t..t + k` of ranges checked above
            // to lie inside their slices.
            unsafe {
                let mask = first_lanes(k);
                let p0 = out0.as_mut_ptr().add(s + t);
                let p1 = out1.as_mut_ptr().add(s + t);
                let d0 = _mm256_maskload_ps(dots[0].as_ptr().add(a + t), mask);
                let d1 = _mm256_maskload_ps(dots[1].as_ptr().add(a + t), mask);
                let d2 = _mm256_maskload_ps(dots[2].as_ptr().add(a + t), mask);
                let o0 = _mm256_add_ps(_mm256_maskload_ps(p0, mask), d0);
                let o1 = _mm256_add_ps(_mm256_add_ps(_mm256_maskload_ps(p1, mask), d1), d2);
                _mm256_maskstore_ps(p0, mask, o0);
                _mm256_maskstore_ps(p1, mask, o1);
            }
            t += k;
        }
        a += n;
    }
}

/// Three rows of [`LANES`] columns side by side: rows `0..3` or `3..6` of one block of a
/// layout from [`transpose_columns`].
type Rows3 = [[Real; LANES]; 3];

/// `alpha * m`, entry by entry, as `[row][column]`: the factor nalgebra's `gemv` forms for
/// each entry of `m` (`alpha * m[(r, k)]`) before it multiplies.
fn scaled(alpha: Real, m: &na::Matrix3<Real>) -> [[Real; 3]; 3] {
    core::array::from_fn(|r| core::array::from_fn(|k| alpha * m[(r, k)]))
}

/// `y += a x` for each of the [`LANES`] columns, `a` already scaled by `gemm`'s alpha
/// ([`scaled`]): each entry's arithmetic is nalgebra's `gemm(alpha, a, x, 1.0)` on a 3-row
/// matrix, which goes column by column through `gemv` and `axcpy`: `y = (alpha a[r][k])
/// x[k] + 1 y` for `k` in order, unfused.
#[inline(always)]
fn add_product(y: &mut Rows3, a: &[[Real; 3]; 3], x: &Rows3) {
    for k in 0..3 {
        for r in 0..3 {
            let ark = a[r][k];
            for l in 0..LANES {
                y[r][l] = ark * x[k][l] + y[r][l];
            }
        }
    }
}

/// Rows `row0..row0 + 3` of block `block` of a [`transpose_columns`] layout, its lanes from
/// `valid` on read as +0.
#[inline(always)]
fn load_rows(src: &[Real], block: usize, row0: usize, valid: usize) -> Rows3 {
    let mut rows = [[0.0; LANES]; 3];
    if valid == 0 {
        // Past the parent's blocks.
        return rows;
    }
    for (r, row) in rows.iter_mut().enumerate() {
        let at = (block * SPATIAL_DIM + row0 + r) * LANES;
        // Whole blocks read and masked: a copy of `valid` entries into the stack, then read
        // back as one register, stalls the store forwarding.
        let src: &[Real; LANES] = src[at..at + LANES].try_into().unwrap();
        for l in 0..LANES {
            row[l] = if l < valid { src[l] } else { 0.0 };
        }
    }
    rows
}

/// [`load_rows`] with AVX's masked loads: the lanes from `valid` on read as +0, as there.
///
/// # Safety
/// The CPU must have AVX.
#[cfg(all(feature = "std", feature = "f32", target_arch = "x86_64"))]
#[target_feature(enable = "avx")]
#[inline]
unsafe fn load_rows_avx(src: &[Real], block: usize, row0: usize, valid: usize) -> Rows3 {
    use super::mass_factor::first_lanes;
    use core::arch::x86_64::{_mm256_maskload_ps, _mm256_storeu_ps};
    let mut rows = [[0.0; LANES]; 3];
    if valid == 0 {
        // Past the parent's blocks.
        return rows;
    }
    let valid = valid.min(LANES);
    for (r, row) in rows.iter_mut().enumerate() {
        let at = (block * SPATIAL_DIM + row0 + r) * LANES;
        let src = &src[at..at + LANES];
        // SAFETY: the CPU has AVX (the caller's contract); the load reads inside `src`,
        // `LANES` entries long.
        unsafe {
            let mask = first_lanes(valid);
            _mm256_storeu_ps(row.as_mut_ptr(), _mm256_maskload_ps(src.as_ptr(), mask));
        }
    }
    rows
}

#[inline(always)]
fn store_rows(dst: &mut [Real], block: usize, row0: usize, rows: &Rows3) {
    for (r, row) in rows.iter().enumerate() {
        let at = (block * SPATIAL_DIM + row0 + r) * LANES;
        dst[at..at + LANES].copy_from_slice(row);
    }
}

/// A link's Coriolis terms from its parent's (`cor`, `parent_cor`: `coriolis_v` in rows
/// `0..3`, `coriolis_w` in rows `3..6`; `parent_jt` the parent's body Jacobian; all in the
/// layout of [`transpose_columns`]; the parent's first `parent_width` columns are the
/// child's first): `v = pv + m[0] pw + m[1] pj + m[2] pj + m[3] pj`, `w = pw + m[4] pj`,
/// each product added in that order ([`add_product`]), `pj` the parent's angular rows. The
/// child's other columns start from +0, as upstream's, where the parent's terms are +0.
fn coriolis_from_parent(
    cor: &mut [Real],
    parent_cor: &[Real],
    parent_jt: &[Real],
    parent_width: usize,
    m: &[[[Real; 3]; 3]; 5],
) {
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    if std::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU has AVX, checked just above.
        unsafe { coriolis_from_parent_avx(cor, parent_cor, parent_jt, parent_width, m) };
        return;
    }
    coriolis_from_parent_any(cor, parent_cor, parent_jt, parent_width, m, load_rows);
}

/// [`coriolis_from_parent_any`] compiled for CPUs with AVX (no FMA: the same arithmetic).
#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx")]
unsafe fn coriolis_from_parent_avx(
    cor: &mut [Real],
    parent_cor: &[Real],
    parent_jt: &[Real],
    parent_width: usize,
    m: &[[[Real; 3]; 3]; 5],
) {
    #[cfg(feature = "f32")]
    // SAFETY (of `load_rows_avx`): this function runs only where the CPU has AVX.
    coriolis_from_parent_any(
        cor,
        parent_cor,
        parent_jt,
        parent_width,
        m,
        |s, b, r, v| unsafe { load_rows_avx(s, b, r, v) },
    );
    #[cfg(not(feature = "f32"))]
    coriolis_from_parent_any(cor, parent_cor, parent_jt, parent_width, m, load_rows);
}

#[inline(always)]
fn coriolis_from_parent_any(
    cor: &mut [Real],
    parent_cor: &[Real],
    parent_jt: &[Real],
    parent_width: usize,
    m: &[[[Real; 3]; 3]; 5],
    load_rows: impl Fn(&[Real], usize, usize, usize) -> Rows3,
) {
    let blocks = cor.len() / (SPATIAL_DIM * LANES);
    for b in 0..blocks {
        let valid = parent_width.saturating_sub(b * LANES).min(LANES);
        let pv = load_rows(parent_cor, b, 0, valid);
        let pw = load_rows(parent_cor, b, DIM, valid);
        let pj = load_rows(parent_jt, b, DIM, valid);
        let (mut v, mut w) = (pv, pw);
        add_product(&mut v, &m[0], &pw);
        add_product(&mut v, &m[1], &pj);
        add_product(&mut v, &m[2], &pj);
        add_product(&mut v, &m[3], &pj);
        add_product(&mut w, &m[4], &pj);
        store_rows(cor, b, 0, &v);
        store_rows(cor, b, DIM, &w);
    }
}

/// A link's own Coriolis terms added (`v += m[0] w + m[1] j + m[2] j`, `j` its angular
/// rows in `jt`), then melded: `icd` gets `v` scaled by `mass_dt` row by row over
/// `dt_inertia w` (nalgebra's `gemm(dt, inertia, w, 0.0)`: the first product stored, the
/// next two added). Same layout as [`coriolis_from_parent`].
fn coriolis_meld(
    cor: &mut [Real],
    jt: &[Real],
    m: &[[[Real; 3]; 3]; 3],
    mass_dt: [Real; 3],
    dt_inertia: &[[Real; 3]; 3],
    icd: &mut [Real],
) {
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    if std::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU has AVX, checked just above.
        unsafe { coriolis_meld_avx(cor, jt, m, mass_dt, dt_inertia, icd) };
        return;
    }
    coriolis_meld_any(cor, jt, m, mass_dt, dt_inertia, icd);
}

/// [`coriolis_meld_any`] compiled for CPUs with AVX (no FMA: the same arithmetic).
#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx")]
unsafe fn coriolis_meld_avx(
    cor: &mut [Real],
    jt: &[Real],
    m: &[[[Real; 3]; 3]; 3],
    mass_dt: [Real; 3],
    dt_inertia: &[[Real; 3]; 3],
    icd: &mut [Real],
) {
    coriolis_meld_any(cor, jt, m, mass_dt, dt_inertia, icd)
}

#[inline(always)]
fn coriolis_meld_any(
    cor: &mut [Real],
    jt: &[Real],
    m: &[[[Real; 3]; 3]; 3],
    mass_dt: [Real; 3],
    dt_inertia: &[[Real; 3]; 3],
    icd: &mut [Real],
) {
    let blocks = cor.len() / (SPATIAL_DIM * LANES);
    for b in 0..blocks {
        let mut v = load_rows(cor, b, 0, LANES);
        let w = load_rows(cor, b, DIM, LANES);
        let j = load_rows(jt, b, DIM, LANES);
        add_product(&mut v, &m[0], &w);
        add_product(&mut v, &m[1], &j);
        add_product(&mut v, &m[2], &j);
        store_rows(cor, b, 0, &v);

        let mut iv = v;
        for (row, md) in iv.iter_mut().zip(mass_dt) {
            for x in row.iter_mut() {
                *x *= md;
            }
        }
        let mut iw = [[0.0; LANES]; 3];
        for (r, row) in iw.iter_mut().enumerate() {
            let a0 = dt_inertia[r][0];
            for l in 0..LANES {
                row[l] = a0 * w[0][l];
            }
        }
        for k in 1..3 {
            for (r, row) in iw.iter_mut().enumerate() {
                let ark = dt_inertia[r][k];
                for l in 0..LANES {
                    row[l] = ark * w[k][l] + row[l];
                }
            }
        }
        store_rows(icd, b, 0, &iv);
        store_rows(icd, b, DIM, &iw);
    }
}

/// [`fused_product`] on CPUs with FMA: an output column's [`SPATIAL_DIM`] entries side by
/// side in one register (`m`'s columns held in registers, `j[k, c]` broadcast), each lane
/// the same chain of fused multiply-adds in the same order (`fma(a, b, c)` is `a b + c`
/// rounded once, whichever operand is the matrix's), where the compiler's loop did one
/// entry at a time.
///
/// # Safety
/// The CPU must have AVX and FMA.
#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx,fma")]
unsafe fn fused_product_fma(out: &mut [Real], m: &[Real], j: &[Real], s: usize, n: usize) {
    #[cfg(feature = "f32")]
    {
        use super::mass_factor::first_lanes;
        use core::arch::x86_64::{
            __m256, _mm256_fmadd_ps, _mm256_maskload_ps, _mm256_maskstore_ps, _mm256_set1_ps,
            _mm256_setzero_ps,
        };
        const D: usize = SPATIAL_DIM;
        assert!(D <= LANES && m.len() >= D * D);
        assert!(j.len() >= (s + n) * D && out.len() >= (s + n) * D);
        // SAFETY: the CPU has AVX and FMA (the caller's contract); each masked load and
        // store touches the first `D` lanes only: a column of `m`, or column `c` of `j` or
        // `out`, inside the lengths checked above.
        unsafe {
            let mask = first_lanes(D);
            let columns: [__m256; D] =
                core::array::from_fn(|k| _mm256_maskload_ps(m.as_ptr().add(k * D), mask));
            for c in s..s + n {
                let jc = &j[c * D..c * D + D];
                let mut acc = _mm256_setzero_ps();
                for (column, jk) in columns.iter().zip(jc) {
                    acc = _mm256_fmadd_ps(*column, _mm256_set1_ps(*jk), acc);
                }
                _mm256_maskstore_ps(out.as_mut_ptr().add(c * D), mask, acc);
            }
        }
    }
    #[cfg(not(feature = "f32"))]
    fused_product(out, m, j, s, n)
}

/// Column-major `out[.., c] = m * j[.., c]` for `c` in `s..s + n`, each entry
/// `fma(m[r, 5], j[5, c], ... fma(m[r, 0], j[0, c], 0))`.
#[cfg(feature = "std")]
#[inline(always)]
fn fused_product(out: &mut [Real], m: &[Real], j: &[Real], s: usize, n: usize) {
    const D: usize = SPATIAL_DIM;
    for c in s..s + n {
        let jc = &j[c * D..c * D + D];
        let oc = &mut out[c * D..c * D + D];
        for (r, o) in oc.iter_mut().enumerate() {
            let mut acc: Real = 0.0;
            for (k, jk) in jc.iter().enumerate() {
                acc = m[k * D + r].mul_add(*jk, acc);
            }
            *o = acc;
        }
    }
}

#[cfg(test)]
mod test {
    use super::IndexSequence;
    use crate::alloc_prelude::*;
    use crate::dynamics::{ImpulseJointSet, IslandManager};
    #[cfg(feature = "dim3")]
    use crate::math::Vector;
    use crate::math::{Real, SPATIAL_DIM};
    use crate::prelude::{
        ColliderSet, MultibodyJointHandle, MultibodyJointSet, RevoluteJoint, RigidBodyBuilder,
        RigidBodySet, SoftBodySet,
    };
    use na::{DVector, RowDVector};

    #[test]
    fn test_multibody_append() {
        let mut bodies = RigidBodySet::new();
        let mut joints = MultibodyJointSet::new();

        let a = bodies.insert(RigidBodyBuilder::dynamic());
        let b = bodies.insert(RigidBodyBuilder::dynamic());
        let c = bodies.insert(RigidBodyBuilder::dynamic());
        let d = bodies.insert(RigidBodyBuilder::dynamic());

        #[cfg(feature = "dim2")]
        let joint = RevoluteJoint::new();
        #[cfg(feature = "dim3")]
        let joint = RevoluteJoint::new(Vector::X);

        let mb_handle = joints.insert(a, b, joint, true).unwrap();
        joints.insert(c, d, joint, true).unwrap();
        joints.insert(b, c, joint, true).unwrap();

        assert_eq!(joints.get(mb_handle).unwrap().0.ndofs, SPATIAL_DIM + 3);
    }

    #[test]
    fn test_multibody_insert() {
        let mut rnd = oorandom::Rand32::new(1234);

        for k in 0..10 {
            let mut bodies = RigidBodySet::new();
            let mut multibody_joints = MultibodyJointSet::new();

            let num_links = 100;
            let mut handles = vec![];

            for _ in 0..num_links {
                handles.push(bodies.insert(RigidBodyBuilder::dynamic()));
            }

            let mut insertion_id: Vec<_> = (0..num_links - 1).collect();

            #[cfg(feature = "dim2")]
            let joint = RevoluteJoint::new();
            #[cfg(feature = "dim3")]
            let joint = RevoluteJoint::new(Vector::X);

            match k {
                0 => {} // Remove in insertion order.
                1 => {
                    // Remove from leaf to root.
                    insertion_id.reverse();
                }
                _ => {
                    // Shuffle the vector a bit.
                    // (This test checks multiple shuffle arrangements due to k > 2).
                    for l in 0..num_links - 1 {
                        insertion_id.swap(l, rnd.rand_range(0..num_links as u32 - 1) as usize);
                    }
                }
            }

            let mut mb_handle = MultibodyJointHandle::invalid();
            for i in insertion_id {
                mb_handle = multibody_joints
                    .insert(handles[i], handles[i + 1], joint, true)
                    .unwrap();
            }

            assert_eq!(
                multibody_joints.get(mb_handle).unwrap().0.ndofs,
                SPATIAL_DIM + num_links - 1
            );
        }
    }

    #[test]
    fn test_multibody_remove() {
        let mut rnd = oorandom::Rand32::new(1234);

        for k in 0..10 {
            let mut bodies = RigidBodySet::new();
            let mut multibody_joints = MultibodyJointSet::new();
            let mut colliders = ColliderSet::new();
            let mut impulse_joints = ImpulseJointSet::new();
            let mut islands = IslandManager::new();
            let mut soft_bodies = SoftBodySet::new();

            let num_links = 100;
            let mut handles = vec![];

            for _ in 0..num_links {
                handles.push(bodies.insert(RigidBodyBuilder::dynamic()));
            }

            #[cfg(feature = "dim2")]
            let joint = RevoluteJoint::new();
            #[cfg(feature = "dim3")]
            let joint = RevoluteJoint::new(Vector::X);

            for i in 0..num_links - 1 {
                multibody_joints
                    .insert(handles[i], handles[i + 1], joint, true)
                    .unwrap();
            }

            match k {
                0 => {} // Remove in insertion order.
                1 => {
                    // Remove from leaf to root.
                    handles.reverse();
                }
                _ => {
                    // Shuffle the vector a bit.
                    // (This test checks multiple shuffle arrangements due to k > 2).
                    for l in 0..num_links {
                        handles.swap(l, rnd.rand_range(0..num_links as u32) as usize);
                    }
                }
            }

            for handle in handles {
                bodies.remove(
                    handle,
                    &mut islands,
                    &mut colliders,
                    &mut impulse_joints,
                    &mut multibody_joints,
                    &mut soft_bodies,
                    true,
                );
            }
        }
    }

    fn test_sequence() -> IndexSequence {
        let mut seq = IndexSequence::new();
        seq.remove(2);
        seq.remove(3);
        seq.remove(4);
        seq.keep(5);
        seq.keep(6);
        seq.remove(7);
        seq.keep(8);
        seq
    }

    #[test]
    fn index_sequence_rearrange_columns() {
        let seq = test_sequence();
        let mut vec = RowDVector::from_fn(10, |_, c| c as Real);
        seq.rearrange_columns(&mut vec, true);
        assert_eq!(
            vec,
            RowDVector::from(vec![0.0, 1.0, 5.0, 6.0, 8.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        );
    }

    #[test]
    fn index_sequence_rearrange_rows() {
        let seq = test_sequence();
        let mut vec = DVector::from_fn(10, |r, _| r as Real);
        seq.rearrange_rows(&mut vec, true);
        assert_eq!(
            vec,
            DVector::from(vec![0.0, 1.0, 5.0, 6.0, 8.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        );
        seq.inv_rearrange_rows(&mut vec);
        assert_eq!(
            vec,
            DVector::from(vec![0.0, 1.0, 0.0, 0.0, 0.0, 5.0, 6.0, 0.0, 8.0, 0.0])
        );
    }

    #[test]
    fn index_sequence_with_rearranged_rows_mut() {
        let seq = test_sequence();
        let mut vec = DVector::from_fn(10, |r, _| r as Real);
        seq.with_rearranged_rows_mut(&mut vec, |v| {
            assert_eq!(v.len(), 5);
            assert_eq!(*v, DVector::from(vec![0.0, 1.0, 5.0, 6.0, 8.0]));
            *v *= 10.0;
        });
        assert_eq!(
            vec,
            DVector::from(vec![0.0, 10.0, 0.0, 0.0, 0.0, 50.0, 60.0, 0.0, 80.0, 0.0])
        );
    }

    /// A branched tree (free root, three 2-link legs) with every link moving, and its bodies.
    #[cfg(feature = "dim3")]
    fn moving_three_legged_tree() -> (RigidBodySet, super::Multibody) {
        moving_tree(2)
    }

    /// A branched tree (free root, three legs of `links` links) with every link moving.
    #[cfg(feature = "dim3")]
    fn moving_tree(links: usize) -> (RigidBodySet, super::Multibody) {
        use crate::dynamics::MassProperties;
        let mut bodies = RigidBodySet::new();
        let mut joints = MultibodyJointSet::new();
        let mut rnd = oorandom::Rand32::new(7);
        let body = |bodies: &mut RigidBodySet, x: Real| {
            // Principal axes turned from the body's, so every inertia has off-diagonal terms.
            let m = MassProperties::with_principal_inertia_frame(
                Vector::new(0.1, -0.05, 0.02),
                1.0 + x,
                Vector::new(0.3 + x, 0.2, 0.1 + 0.5 * x),
                crate::math::Rotation::from_scaled_axis(Vector::new(0.3, -0.2 + 0.1 * x, 0.4)),
            );
            bodies.insert(
                RigidBodyBuilder::dynamic()
                    .translation(Vector::new(x, 0.3 * x, -0.2 * x))
                    .additional_mass_properties(m),
            )
        };
        let root = body(&mut bodies, 0.0);
        let mut handle = None;
        for leg in 0..3 {
            let axes = [Vector::X, Vector::Y, Vector::Z];
            let mut parent = root;
            for k in 0..links {
                let link = body(&mut bodies, 1.0 + 0.5 * k as Real + leg as Real);
                let h = joints
                    .insert(parent, link, RevoluteJoint::new(axes[(leg + k) % 3]), true)
                    .unwrap();
                handle.get_or_insert(h);
                parent = link;
            }
        }
        let colliders = ColliderSet::new();
        let handles: Vec<_> = bodies.iter().map(|(h, _)| h).collect();
        for h in handles {
            bodies[h].recompute_mass_properties_from_colliders(&colliders);
        }
        let (mb, _) = joints.get_mut(handle.unwrap()).unwrap();
        for v in mb.velocities.iter_mut() {
            *v = rnd.rand_float() * 4.0 - 2.0;
        }
        mb.forward_kinematics(&bodies, false);
        mb.update_velocities(&mut bodies);
        (bodies, mb.clone())
    }

    /// Every bit forward kinematics computes: each link's poses and shifts, and the body
    /// Jacobians.
    #[cfg(feature = "dim3")]
    fn kinematics_bits(mb: &super::Multibody) -> Vec<u32> {
        let mut bits = Vec::new();
        for link in mb.links.iter() {
            for pose in [&link.local_to_world, &link.local_to_parent] {
                bits.extend(pose.rotation.to_array().map(Real::to_bits));
                bits.extend(pose.translation.to_array().map(Real::to_bits));
            }
            for shift in [link.shift02, link.shift23] {
                bits.extend(shift.to_array().map(Real::to_bits));
            }
        }
        for j in &mb.body_jacobians {
            bits.extend(j.iter().map(|x| x.to_bits()));
        }
        bits
    }

    /// Strider patch: forward kinematics that finds what it reads unchanged since its last
    /// call computes nothing (the pipeline calls it at both ends of a step); one that finds
    /// anything it reads changed (a joint moved, the root body moved or made fixed, a
    /// link's centre of mass or joint frame changed, also on a copy) computes the bits a
    /// multibody that never skipped computes.
    #[cfg(feature = "dim3")]
    #[test]
    fn forward_kinematics_skips_only_what_is_unchanged() {
        use crate::dynamics::{MassProperties, RigidBodyType};
        use crate::geometry::ColliderSet;
        let (mut bodies, mut mb) = moving_three_legged_tree();
        let fresh = |mb: &super::Multibody, bodies: &RigidBodySet| {
            let mut fresh = mb.clone();
            fresh.kinematics_inputs.clear();
            fresh.forward_kinematics(bodies, true);
            kinematics_bits(&fresh)
        };
        // Checks that a call after `change` recomputes: the bits of one that never
        // skipped, and not those before the change.
        let recomputes = |mb: &mut super::Multibody, bodies: &RigidBodySet, what: &str| {
            let before = kinematics_bits(mb);
            mb.forward_kinematics(bodies, true);
            let after = kinematics_bits(mb);
            assert_ne!(after, before, "{what}: nothing changed");
            assert_eq!(fresh(mb, bodies), after, "{what}");
        };
        // The root somewhere general, as a walking robot's is, and its body where the
        // step's end leaves it.
        let root = mb.links[0].rigid_body;
        bodies[root].set_position(
            crate::math::Pose::from_parts(
                Vector::new(0.3, 2.1, -0.7),
                crate::math::Rotation::from_scaled_axis(Vector::new(0.2, -0.4, 0.1)),
            ),
            false,
        );
        recomputes(&mut mb, &bodies, "the root placed");
        mb.update_rigid_bodies(&mut bodies, true);

        // Nothing changed (the root's pose read back from its body): nothing recomputed,
        // so a value planted in the outputs stays.
        let computed = kinematics_bits(&mb);
        let original = mb.links[2].shift02;
        mb.links[2].shift02 = original + Vector::new(1.0, 0.0, 0.0);
        mb.forward_kinematics(&bodies, true);
        assert_ne!(
            mb.links[2].shift02, original,
            "recomputed with nothing changed"
        );
        mb.links[2].shift02 = original;
        assert_eq!(kinematics_bits(&mb), computed);

        let mut displacement = vec![0.0; mb.ndofs()];
        displacement[7] = 0.125;
        mb.apply_displacements(&displacement);
        recomputes(&mut mb, &bodies, "a joint moved");

        let mut pose = *bodies[root].position();
        pose.translation.y += 0.25;
        bodies[root].set_position(pose, false);
        recomputes(&mut mb, &bodies, "the root body moved");

        let link = mb.links[4].rigid_body;
        bodies[link].set_additional_mass_properties(
            MassProperties::new(Vector::new(0.2, 0.1, -0.1), 2.0, Vector::new(0.1, 0.2, 0.3)),
            false,
        );
        bodies[link].recompute_mass_properties_from_colliders(&ColliderSet::new());
        recomputes(&mut mb, &bodies, "a centre of mass moved");

        let frame = crate::math::Pose::from_translation(Vector::new(0.05, 0.0, 0.1));
        mb.link_mut(3).unwrap().joint.data.set_local_frame2(frame);
        recomputes(&mut mb, &bodies, "a joint frame changed");

        let mut copy = mb.clone();
        copy.apply_displacements(&displacement);
        recomputes(&mut copy, &bodies, "a copy's joint moved");

        bodies[root].set_body_type(RigidBodyType::Fixed, false);
        recomputes(&mut mb, &bodies, "the root made fixed");
    }

    /// Strider patch: the sparse mass-matrix assembly equals the upstream dense one on a
    /// branched tree (free root, three 2-link legs) with every link moving.
    #[cfg(feature = "dim3")]
    #[test]
    fn sparse_mass_matrix_matches_dense() {
        let (bodies, mut mb) = moving_three_legged_tree();
        let dt = 1.0 / 240.0;
        let mut dense = mb.clone();
        mb.update_mass_matrix(dt, &bodies);
        dense.update_mass_matrix_dense(dt, &bodies);
        for (sparse, full) in [
            (&mb.augmented_mass, &dense.augmented_mass),
            (&mb.acc_augmented_mass, &dense.acc_augmented_mass),
        ] {
            assert!(full.iter().any(|x| *x != 0.0));
            let scale = full.amax();
            let diff = (sparse - full).amax();
            assert!(
                diff <= 1.0e-5 * scale,
                "sparse differs by {diff} (scale {scale})"
            );
        }
    }

    /// Strider patch: each link's Coriolis terms, computed over its nonzero columns in
    /// blocks of lanes, have the bits of upstream's dense `gemm`s, on legs of two links (one
    /// block a link) and four (a second block, part of it the parent's padding).
    #[cfg(feature = "dim3")]
    #[test]
    fn coriolis_blocks_match_dense_bit_for_bit() {
        use super::LANES;
        for links in [2, 4] {
            let (bodies, mut mb) = moving_tree(links);
            let dt = 1.0 / 240.0;
            let mut dense = mb.clone();
            mb.update_mass_matrix(dt, &bodies);
            let (cv, cw, melded) = dense.update_mass_matrix_dense(dt, &bodies);
            let (mut checked, mut nonzero, mut second_block) = (0, 0, false);
            for (i, ranges) in mb.workspace.col_ranges.iter().enumerate() {
                let cor = &mb.workspace.coriolis[i];
                let mut a = 0;
                for &(s, n) in ranges {
                    for c in s..s + n {
                        let (block, lane) = (a / LANES, a % LANES);
                        second_block |= block > 0;
                        for r in 0..3 {
                            for (row0, full) in [(0, cv[i][(r, c)]), (3, cw[i][(r, c)])] {
                                let ours = cor[(block * SPATIAL_DIM + row0 + r) * LANES + lane];
                                assert_eq!(ours.to_bits(), full.to_bits(), "link {i} column {c}");
                                checked += 1;
                                nonzero += (full != 0.0) as usize;
                            }
                        }
                        a += 1;
                    }
                }
            }
            // Not all zeros (the root's terms and some rows are, by structure).
            assert!(nonzero * 4 > checked, "{nonzero} of {checked}");
            assert_eq!(second_block, links > 2);
            // The last link's terms melded with its mass and `dt` (`coriolis_dt` holds the
            // last link's), against upstream's `component_mul` and `gemm(dt, inertia, w, 0)`.
            let last = mb.links.len() - 1;
            let icd = &mb.workspace.coriolis_dt;
            let mut a = 0;
            for &(s, n) in &mb.workspace.col_ranges[last] {
                for c in s..s + n {
                    let (block, lane) = (a / LANES, a % LANES);
                    for k in 0..SPATIAL_DIM {
                        let ours = icd[(block * SPATIAL_DIM + k) * LANES + lane];
                        let full = melded[last][(k, c)];
                        assert_eq!(ours.to_bits(), full.to_bits(), "melded row {k} column {c}");
                    }
                    a += 1;
                }
            }
        }
    }

    /// Strider patch: the Coriolis kernels give the same bits with AVX as without.
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[test]
    fn coriolis_kernels_are_the_same_with_avx() {
        use super::{
            LANES, coriolis_from_parent_any, coriolis_from_parent_avx, coriolis_meld_any,
            coriolis_meld_avx,
        };
        if !std::is_x86_feature_detected!("avx") {
            return;
        }
        let mut state = 0x5eed_1234_u32;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            ((state >> 8) as Real / (1u32 << 24) as Real - 0.5) * 4.0
        };
        let len = 2 * SPATIAL_DIM * LANES;
        let mut fill = |n: usize| (0..n).map(|_| next()).collect::<Vec<Real>>();
        let (parent_cor, parent_jt, jt) = (fill(len / 2), fill(len / 2), fill(len));
        let m5: [[[Real; 3]; 3]; 5] = {
            let v = fill(45);
            core::array::from_fn(|p| {
                core::array::from_fn(|r| core::array::from_fn(|k| v[p * 9 + r * 3 + k]))
            })
        };
        let m3: [[[Real; 3]; 3]; 3] = core::array::from_fn(|p| m5[p]);
        let bits = |x: &[Real]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        // Parents whose columns fill part of a block, a whole one, and one column.
        for width in [1, 8, 5] {
            let (mut plain, mut avx) = (vec![0.0; len], vec![0.0; len]);
            coriolis_from_parent_any(
                &mut plain,
                &parent_cor,
                &parent_jt,
                width,
                &m5,
                super::load_rows,
            );
            // SAFETY: the CPU has AVX, checked above.
            unsafe { coriolis_from_parent_avx(&mut avx, &parent_cor, &parent_jt, width, &m5) };
            assert!(plain.iter().any(|x| *x != 0.0));
            assert_eq!(bits(&plain), bits(&avx), "parent width {width}");
        }
        let (mut plain, mut avx) = (vec![0.0; len], vec![0.0; len]);
        coriolis_from_parent_any(
            &mut plain,
            &parent_cor,
            &parent_jt,
            5,
            &m5,
            super::load_rows,
        );
        // SAFETY: the CPU has AVX, checked above.
        unsafe { coriolis_from_parent_avx(&mut avx, &parent_cor, &parent_jt, 5, &m5) };
        let (mut icd_plain, mut icd_avx) = (vec![0.0; len], vec![0.0; len]);
        coriolis_meld_any(
            &mut plain,
            &jt,
            &m3,
            [1.5, -0.5, 2.0],
            &m5[4],
            &mut icd_plain,
        );
        // SAFETY: as above.
        unsafe { coriolis_meld_avx(&mut avx, &jt, &m3, [1.5, -0.5, 2.0], &m5[4], &mut icd_avx) };
        assert_eq!(bits(&plain), bits(&avx));
        assert!(icd_plain.iter().any(|x| *x != 0.0));
        assert_eq!(bits(&icd_plain), bits(&icd_avx));
    }

    /// Strider patch: a world put back from copies of its sets (as the worker's joint drives
    /// do to take a step again) steps as the world they were copied from, bit for bit, with
    /// its robot on the ground: a copy of a multibody keeps all its state (its workspace is
    /// scratch and copied as sizes only), and so does a copy taken into an older copy's
    /// buffers (`clone_from`, as the drives take theirs).
    #[cfg(feature = "dim3")]
    #[test]
    fn a_world_put_back_from_copies_steps_the_same() {
        use crate::prelude::{ColliderBuilder, PhysicsWorld, RevoluteJointBuilder};
        let mut world = PhysicsWorld::new();
        world.insert(
            RigidBodyBuilder::fixed().translation(Vector::new(0.0, -0.5, 0.0)),
            ColliderBuilder::cuboid(50.0, 0.5, 50.0),
        );
        // Awake throughout, and its joints set swinging before every step (below), so that
        // every step moves the robot and its feet strike and leave the ground.
        let body = |at: Vector| RigidBodyBuilder::dynamic().translation(at).can_sleep(false);
        let (root, _) = world.insert(
            body(Vector::new(0.0, 1.0, 0.0)),
            ColliderBuilder::cuboid(0.5, 0.1, 0.3),
        );
        let mut first_joint = None;
        for leg in 0..4 {
            let (x, z) = ([0.4, -0.4][leg % 2], [0.3, -0.3][leg / 2]);
            let mut parent = root;
            for k in 0..3 {
                let (link, _) = world.insert(
                    body(Vector::new(x, 0.8 - 0.25 * k as Real, z)),
                    ColliderBuilder::capsule_y(0.1, 0.05),
                );
                let axis = if k == 0 { Vector::Y } else { Vector::Z };
                let anchor = if k == 0 {
                    Vector::new(x, -0.1, z)
                } else {
                    Vector::new(0.0, -0.125, 0.0)
                };
                let joint = RevoluteJointBuilder::new(axis)
                    .local_anchor1(anchor)
                    .local_anchor2(Vector::new(0.0, 0.125, 0.0));
                let handle = world.insert_multibody_joint(parent, link, joint).unwrap();
                first_joint.get_or_insert(handle);
                parent = link;
            }
        }
        let first_joint = first_joint.unwrap();
        let mut step = 0;
        let mut run = |world: &mut PhysicsWorld| {
            let mut bits = Vec::new();
            for _ in 0..60 {
                let (mb, _) = world.multibody_joints.get_mut(first_joint).unwrap();
                for (j, v) in mb.generalized_velocity_mut().iter_mut().enumerate().skip(6) {
                    *v = 4.0 * (0.3 * (step % 60) as Real + j as Real).sin();
                }
                step += 1;
                world.step();
                for (_, rb) in world.bodies.iter() {
                    bits.extend(rb.translation().to_array().map(Real::to_bits));
                    bits.extend(rb.linvel().to_array().map(Real::to_bits));
                }
            }
            bits
        };
        run(&mut world);
        let copies = (
            world.bodies.clone(),
            world.colliders.clone(),
            world.multibody_joints.clone(),
            world.islands.clone(),
            world.broad_phase.clone(),
            world.narrow_phase.clone(),
        );
        let first = run(&mut world);
        assert!(
            world
                .narrow_phase
                .contact_pairs()
                .any(|p| p.has_any_active_contact()),
            "the robot never touched the ground"
        );
        world.bodies.clone_from(&copies.0);
        world.colliders.clone_from(&copies.1);
        world.multibody_joints.clone_from(&copies.2);
        world.islands.clone_from(&copies.3);
        world.broad_phase.clone_from(&copies.4);
        world.narrow_phase.clone_from(&copies.5);
        let again = run(&mut world);
        assert!(first == again, "the put-back world stepped otherwise");
        // Copied again into the first copies' buffers (`clone_from`, which reuses them:
        // they hold another state, with other contacts), and put back from them.
        let mut copies = copies;
        copies.0.clone_from(&world.bodies);
        copies.1.clone_from(&world.colliders);
        copies.2.clone_from(&world.multibody_joints);
        copies.3.clone_from(&world.islands);
        copies.4.clone_from(&world.broad_phase);
        copies.5.clone_from(&world.narrow_phase);
        let third = run(&mut world);
        world.bodies.clone_from(&copies.0);
        world.colliders.clone_from(&copies.1);
        world.multibody_joints.clone_from(&copies.2);
        world.islands.clone_from(&copies.3);
        world.broad_phase.clone_from(&copies.4);
        world.narrow_phase.clone_from(&copies.5);
        assert!(
            third == run(&mut world),
            "the world put back from copies taken into old ones stepped otherwise"
        );
        assert!(first != third, "the copies were taken of the same state");
    }

    /// Strider patch: the body Jacobians computed over each link's nonzero columns have the
    /// bits of the upstream dense computation, zeros included.
    #[cfg(feature = "dim3")]
    #[test]
    fn sparse_body_jacobians_match_dense_bit_for_bit() {
        let (_, mut mb) = moving_three_legged_tree();
        let mut dense = mb.clone();
        mb.update_body_jacobians();
        dense.update_body_jacobians_dense();
        let mut nonzero = 0;
        for (sparse, full) in mb.body_jacobians.iter().zip(&dense.body_jacobians) {
            let bits =
                |j: &crate::math::Jacobian<Real>| j.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(sparse), bits(full));
            nonzero += full.iter().filter(|x| **x != 0.0).count();
        }
        assert!(nonzero > 0);
    }

    /// Strider patch: a contact's rows solved together (`fill_jacobians_unsolved`, then
    /// `solve_jacobians`, then `jacobian_dot`) give every row the bits `fill_jacobians`
    /// gives it alone, for 1 to 12 rows on every link. Fails if the batched solve reorders
    /// or reassociates any entry's operations.
    #[cfg(feature = "dim3")]
    #[test]
    fn batched_jacobian_solves_match_one_by_one() {
        let (bodies, mut mb) = moving_three_legged_tree();
        mb.update_mass_matrix(1.0 / 240.0, &bodies);
        let n = mb.ndofs();
        let mut rnd = oorandom::Rand32::new(11);
        let mut dir = || {
            Vector::new(
                rnd.rand_float() * 2.0 - 1.0,
                rnd.rand_float() * 2.0 - 1.0,
                rnd.rand_float() * 2.0 - 1.0,
            )
        };
        for rows in [1, 2, 5, 12] {
            let mut alone = crate::math::DVector::zeros(rows * 2 * n);
            let mut batched = crate::math::DVector::zeros(rows * 2 * n);
            let (mut id_alone, mut id_batched) = (0, 0);
            let mut ids = vec![];
            let mut dots = vec![];
            for r in 0..rows {
                let (link, force, torque) = (r % mb.num_links(), dir(), dir());
                dots.push(
                    mb.fill_jacobians(link, force, torque, &mut id_alone, &mut alone)
                        .0,
                );
                ids.push(id_batched);
                mb.fill_jacobians_unsolved(link, force, torque, &mut id_batched, &mut batched);
            }
            assert_eq!(id_alone, id_batched);
            mb.solve_jacobians(&ids, &mut batched);
            let bits = |v: &crate::math::DVector| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert!(alone.iter().skip(n).any(|x| *x != 0.0));
            assert_eq!(bits(&alone), bits(&batched), "{rows} rows");
            for (id, dot) in ids.iter().zip(&dots) {
                assert_eq!(mb.jacobian_dot(*id, &batched).to_bits(), dot.to_bits());
            }
        }
    }

    /// Strider patch: the mass matrices' `Jᵀ W` blocks, eight entries side by side and three
    /// products in one pass, have the bits nalgebra's `gemm_tr` gave block by block and
    /// product by product (the Coriolis one added after the other), with or without AVX, for
    /// ranges of one to six blocks of lanes (the last on the heap). Fails if an entry's dot
    /// product is reordered, started from a non-zero, fused, or added to another block's
    /// entry, or if the two products into one matrix are added the other way round.
    #[cfg(feature = "std")]
    #[test]
    fn transposed_products_match_gemm_tr_bit_for_bit() {
        use super::{transpose_columns, transposed_products_add, transposed_products_add_any};
        use crate::math::{Jacobian, Real};
        use na::DMatrix;
        let mut state = 0x1234_5678_u32;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            ((state >> 8) as Real / (1u32 << 24) as Real - 0.5) * 40.0
        };
        let ndofs = 48;
        let j = Jacobian::<Real>::from_fn(ndofs, |_, _| next());
        let w0 = Jacobian::<Real>::from_fn(ndofs, |_, _| next());
        let w1 = Jacobian::<Real>::from_fn(ndofs, |_, _| next());
        let c = Jacobian::<Real>::from_fn(ndofs, |_, _| next());
        let start0 = DMatrix::<Real>::from_fn(ndofs, ndofs, |_, _| next());
        let start1 = DMatrix::<Real>::from_fn(ndofs, ndofs, |_, _| next());
        let bits = |x: &DMatrix<Real>| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        // The last two end at the matrix's last row (AVX's masked loads and stores reach
        // no further than the range).
        let cases: [&[(usize, usize)]; 8] = [
            &[(0, 6)],
            &[(0, 9)],
            &[(0, 6), (9, 3)],
            &[(0, 6), (12, 1), (20, 2)],
            &[(3, 8), (16, 8), (30, 1)],
            &[(0, 45)],
            &[(0, 6), (45, 3)],
            &[(0, 48)],
        ];
        for ranges in cases {
            let (mut ref0, mut ref1) = (start0.clone(), start1.clone());
            for (target, w) in [(0, &w0), (1, &w1), (1, &c)] {
                let reference = if target == 0 { &mut ref0 } else { &mut ref1 };
                for &(sa, na_) in ranges {
                    for &(sb, nb) in ranges {
                        reference.view_mut((sa, sb), (na_, nb)).gemm_tr(
                            1.0,
                            &j.columns(sa, na_),
                            &w.columns(sb, nb),
                            1.0,
                        );
                    }
                }
            }
            assert_ne!(bits(&ref0), bits(&start0));
            assert_ne!(bits(&ref1), bits(&start1));
            let (mut jt, mut ct) = (Vec::new(), Vec::new());
            transpose_columns(&mut jt, &j, ranges);
            transpose_columns(&mut ct, &c, ranges);
            let (mut ours0, mut ours1) = (start0.clone(), start1.clone());
            transposed_products_add(
                [ours0.as_mut_slice(), ours1.as_mut_slice()],
                ndofs,
                &jt,
                [w0.as_slice(), w1.as_slice()],
                &ct,
                ranges,
            );
            assert_eq!(bits(&ours0), bits(&ref0), "{ranges:?}");
            assert_eq!(bits(&ours1), bits(&ref1), "{ranges:?}");
            let (mut portable0, mut portable1) = (start0.clone(), start1.clone());
            transposed_products_add_any(
                [portable0.as_mut_slice(), portable1.as_mut_slice()],
                ndofs,
                &jt,
                [w0.as_slice(), w1.as_slice()],
                &ct,
                ranges,
                super::add_dots_any,
            );
            assert_eq!(bits(&portable0), bits(&ref0), "{ranges:?} without AVX");
            assert_eq!(bits(&portable1), bits(&ref1), "{ranges:?} without AVX");
        }
    }

    /// Strider patch: the batched triangular solves give the same bits with AVX as without.
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[test]
    fn batched_solve_is_the_same_with_avx() {
        use super::{solve_rows, solve_rows_avx};
        use crate::math::{MAX_MANIFOLD_POINTS, Real};
        if !std::is_x86_feature_detected!("avx") {
            return;
        }
        let (bodies, mut mb) = moving_three_legged_tree();
        mb.update_mass_matrix(1.0 / 240.0, &bodies);
        assert!(mb.inv_augmented_mass.is_tree());
        let n = mb.ndofs();
        let mut state = 0x0bad_f00d_u32;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            ((state >> 8) as Real / (1u32 << 24) as Real - 0.5) * 4.0
        };
        let x: Vec<[Real; 3 * MAX_MANIFOLD_POINTS]> =
            (0..n).map(|_| core::array::from_fn(|_| next())).collect();
        let (mut plain, mut avx) = (x.clone(), x.clone());
        assert!(mb.inv_augmented_mass.solve_rows(&mut plain));
        // SAFETY: the CPU has AVX, checked above.
        assert!(unsafe { solve_rows_avx(&mb.inv_augmented_mass, &mut avx) });
        let bits = |x: &[[Real; 3 * MAX_MANIFOLD_POINTS]]| {
            x.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>()
        };
        assert_ne!(bits(&plain), bits(&x));
        assert_eq!(bits(&plain), bits(&avx));
        let mut dispatched = x.clone();
        assert!(solve_rows(&mb.inv_augmented_mass, &mut dispatched));
        assert_eq!(bits(&plain), bits(&dispatched));
    }

    /// Strider patch: both augmented mass matrices of moving trees (a free root and three
    /// legs of one to four links; the Coriolis terms make one unsymmetric) are factorised
    /// along the tree, and their solves agree with nalgebra's pivoting LU of the same
    /// matrices to rounding.
    #[cfg(feature = "dim3")]
    #[test]
    fn tree_factors_solve_as_the_dense_lu() {
        for links in 1..=4 {
            let (bodies, mut mb) = moving_tree(links);
            mb.update_mass_matrix(1.0 / 240.0, &bodies);
            let n = mb.ndofs();
            assert!((&mb.acc_augmented_mass - mb.acc_augmented_mass.transpose()).amax() > 0.0);
            for (factor, matrix) in [
                (&mb.inv_augmented_mass, &mb.augmented_mass),
                (&mb.acc_inv_augmented_mass, &mb.acc_augmented_mass),
            ] {
                assert!(factor.is_tree(), "{links} links");
                let b = na::DMatrix::<Real>::from_fn(n, 2, |i, c| {
                    (i as Real + 1.0) * if c == 0 { 1.0 } else { -0.3 }
                });
                let mut x = b.clone();
                factor.solve_mut(&mut x);
                let dense = na::LU::new(matrix.clone()).solve(&b).unwrap();
                let (diff, scale) = ((&x - &dense).amax(), dense.amax());
                assert!(diff <= 1.0e-4 * scale, "{links} links: {diff} of {scale}");
                assert_ne!(x, b);
            }
        }
    }

    /// Strider patch: a contact row's `Jᵀ f` (`fill_jacobians_unsolved`) and the
    /// generalised forces of `update_acceleration` (`add_transposed_product`), computed
    /// over each link's nonzero columns only, have the bits of upstream's products over
    /// all columns (`tr_mul_to`, `gemv_tr`), with wrenches whose negative components make
    /// the zero columns' terms -0.
    #[cfg(feature = "dim3")]
    #[test]
    fn sparse_link_products_match_the_dense_ones() {
        let bits = |v: &[Real]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let wrenches = [
            (Vector::new(0.3, -1.2, 0.7), Vector::new(-0.4, -0.1, -2.0)),
            (
                Vector::new(-1.0, -1.0, -1.0),
                Vector::new(-0.5, -0.25, -3.0),
            ),
        ];
        for links in 1..=4 {
            let (bodies, mut mb) = moving_tree(links);
            mb.update_mass_matrix(1.0 / 240.0, &bodies);
            let n = mb.ndofs();
            let mut sparse_sum = DVector::zeros(n);
            let mut dense_sum = DVector::zeros(n);
            let mut zero_columns = 0;
            for link_id in 0..mb.links.len() {
                let jacobian = &mb.body_jacobians[mb.links[link_id].internal_id];
                for (f, t) in wrenches {
                    let wrench = super::Force::new(f, t);
                    let mut dense = DVector::zeros(n);
                    jacobian.tr_mul_to(wrench.as_vector(), &mut dense);
                    zero_columns += dense.iter().filter(|x| **x == 0.0).count();
                    let mut rows = DVector::from_element(3 + 2 * n, 7.0);
                    let mut j_id = 3;
                    mb.fill_jacobians_unsolved(link_id, f, t, &mut j_id, &mut rows);
                    assert_eq!(j_id, 3 + 2 * n);
                    assert_eq!(bits(&rows.as_slice()[3..3 + n]), bits(dense.as_slice()));
                    assert_eq!(bits(&rows.as_slice()[3 + n..]), bits(dense.as_slice()));

                    let ranges = &mb.workspace.col_ranges[link_id];
                    super::add_transposed_product(
                        &mut sparse_sum,
                        jacobian,
                        wrench.as_vector(),
                        ranges,
                    );
                    dense_sum.gemv_tr(1.0, jacobian, wrench.as_vector(), 1.0);
                    assert_eq!(bits(sparse_sum.as_slice()), bits(dense_sum.as_slice()));
                }
            }
            assert!(zero_columns > 0, "{links} links: every column nonzero");
        }
    }

    /// Strider patch: the spatial products the mass matrix is assembled from have the same
    /// bits whether the CPU has FMA or not (the `fmaf` path is what a CPU without it runs)
    /// and, where this CPU has FMA, the bits nalgebra's `gemm` gave through matrixmultiply's
    /// FMA kernels, so trials are unchanged on such CPUs. Fails if an entry's chain is
    /// reordered, started from a non-zero, or left unfused.
    #[cfg(feature = "std")]
    #[test]
    fn spatial_product_is_fused_and_matches_matrixmultiply() {
        use super::{fused_product, spatial_product};
        use crate::math::{Jacobian, Real, SPATIAL_DIM};
        use na::SMatrix;
        let mut state = 0x2545_f491_u32;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            ((state >> 8) as Real / (1u32 << 24) as Real - 0.5) * 40.0
        };
        let ndofs = 24;
        let m = SMatrix::<Real, SPATIAL_DIM, SPATIAL_DIM>::from_fn(|_, _| next());
        let j = Jacobian::<Real>::from_fn(ndofs, |_, _| next());
        let bits = |x: &Jacobian<Real>| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        for (s, n) in [(0, 6), (0, 9), (6, 3), (9, 3), (15, 5), (0, 24)] {
            let mut ours = Jacobian::zeros(ndofs);
            spatial_product(&mut ours, &m, &j, s, n);
            let mut reference = Jacobian::zeros(ndofs);
            reference
                .columns_mut(s, n)
                .gemm(1.0, &m, &j.columns(s, n), 0.0);
            let fma_cpu = {
                #[cfg(target_arch = "x86_64")]
                {
                    std::is_x86_feature_detected!("fma") && std::is_x86_feature_detected!("avx2")
                }
                #[cfg(not(target_arch = "x86_64"))]
                {
                    false
                }
            };
            if SPATIAL_DIM > 5 && n > 5 {
                let mut soft = Jacobian::zeros(ndofs);
                fused_product(soft.as_mut_slice(), m.as_slice(), j.as_slice(), s, n);
                assert_eq!(bits(&ours), bits(&soft), "columns {s}..{}", s + n);
                let mut unfused = Jacobian::zeros(ndofs);
                for c in s..s + n {
                    for r in 0..SPATIAL_DIM {
                        unfused[(r, c)] =
                            (0..SPATIAL_DIM).fold(0.0, |acc, k| acc + m[(r, k)] * j[(k, c)]);
                    }
                }
                assert_ne!(
                    bits(&ours),
                    bits(&unfused),
                    "columns {s}..{}: not fused",
                    s + n
                );
                if fma_cpu {
                    assert_eq!(bits(&ours), bits(&reference), "columns {s}..{}", s + n);
                }
            } else {
                assert_eq!(bits(&ours), bits(&reference), "columns {s}..{}", s + n);
            }
        }
    }

    /// Strider patch: the energy guard's test on the vectors in place gives upstream's
    /// figure bit for bit: `m * &a` and `m * v` on copies (upstream) against `gemv` into
    /// kept buffers, over a mass-like matrix with structural zeros, with stale buffers and
    /// with none. It fails if a product is summed in another order (by rows, checked).
    #[test]
    fn energy_guard_in_place_matches_upstream_bit_for_bit() {
        use super::energy_excess_in_place;
        use crate::math::{DVector, Real};
        use na::DMatrix;
        let mut state = 0x9e37_79b9_u32;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            ((state >> 8) as Real / (1u32 << 24) as Real - 0.5) * 40.0
        };
        let upstream =
            |m: &DMatrix<Real>, v: &DVector, f: &DVector, fp: &DVector, a: &DVector, dt: Real| {
                let (v, f, fp) = (v.clone(), f.clone(), fp.clone());
                let (v, f, fp) = (v.rows(0, v.len()), f.rows(0, f.len()), fp.rows(0, fp.len()));
                let m = m.view((0, 0), (m.nrows(), m.ncols()));
                let a = a.clone().rows(0, a.len()).into_owned();
                let m_a = m * &a;
                let energy_delta = dt * v.dot(&m_a) + 0.5 * dt * dt * a.dot(&m_a);
                let work = dt * v.dot(&f) + 0.5 * dt * dt * a.dot(&fp);
                let kinetic_energy = 0.5 * v.dot(&(m * v));
                energy_delta - work - (1.0e-2 * kinetic_energy + 1.0e-8)
            };
        let mut products = [DVector::zeros(0), DVector::zeros(0)];
        let mut by_rows_differs = false;
        for (round, n) in [6, 9, 18, 24, 42, 18].into_iter().enumerate() {
            // Zero where neither dof is the other's ancestor, as in a legged tree: the root's
            // six couple with all, each leg's three only with themselves and the root.
            let m = DMatrix::<Real>::from_fn(n, n, |i, j| {
                if i < 6 || j < 6 || (i - 6) / 3 == (j - 6) / 3 {
                    next()
                } else {
                    0.0
                }
            });
            let v = DVector::from_fn(n, |_, _| next());
            let f = DVector::from_fn(n, |_, _| next());
            let fp = DVector::from_fn(n, |_, _| next());
            let a = DVector::from_fn(n, |_, _| next() * 1.0e-3);
            let dt = 1.0 / 240.0;
            let here =
                energy_excess_in_place(m.view((0, 0), (n, n)), &v, &f, &fp, &a, dt, &mut products)
                    .expect("finite accelerations");
            assert_eq!(
                here.to_bits(),
                upstream(&m, &v, &f, &fp, &a, dt).to_bits(),
                "round {round}, {n} dofs"
            );
            // The check can fail: `M a` summed by rows (a dot product each) is other bits.
            let by_rows = DVector::from_fn(n, |i, _| m.row(i).transpose().dot(&a));
            by_rows_differs |= by_rows
                .iter()
                .zip((&m * &a).iter())
                .any(|(x, y)| x.to_bits() != y.to_bits());
        }
        assert!(by_rows_differs, "summing by rows should change some bits");
        let mut bad = DVector::from_element(6, 1.0);
        bad[3] = Real::NAN;
        let m = DMatrix::<Real>::identity(6, 6);
        assert!(
            energy_excess_in_place(
                m.view((0, 0), (6, 6)),
                &bad,
                &bad,
                &bad,
                &bad,
                0.01,
                &mut products
            )
            .is_none()
        );
    }

    /// Strider patch: the workspace's column ranges are recomputed whenever what they are a
    /// function of changes, and only then: two trees whose links have the same first dofs
    /// and dof counts but another parent (a chain and a fork) get their own ranges from one
    /// workspace, and a multibody grown a joint at a time, in shuffled orders, has fresh
    /// ranges after every insertion (it fails if the key leaves out the parent).
    #[test]
    fn cached_column_ranges_follow_the_tree() {
        use super::link_column_ranges;
        use crate::dynamics::joint::multibody_joint::multibody_workspace::MultibodyWorkspace;
        let joint = RevoluteJoint::new(Vector::X);
        let fresh = |mb: &super::Multibody| {
            let mut ranges = Vec::new();
            link_column_ranges(&mb.links, &mut ranges);
            ranges
        };
        // a-b-c against a-b, a-c: links of 6, 1 and 1 dofs either way.
        let tree = |fork: bool| {
            let mut bodies = RigidBodySet::new();
            let mut joints = MultibodyJointSet::new();
            let [a, b, c] = [(); 3].map(|_| bodies.insert(RigidBodyBuilder::dynamic()));
            let h = joints.insert(a, b, joint, true).unwrap();
            joints
                .insert(if fork { a } else { b }, c, joint, true)
                .unwrap();
            joints.get(h).unwrap().0.clone()
        };
        let (chain, fork) = (tree(false), tree(true));
        assert_ne!(fresh(&chain), fresh(&fork));
        let mut workspace = MultibodyWorkspace::new();
        for mb in [&chain, &fork, &fork, &chain] {
            let ranges = workspace.column_ranges(&mb.links);
            assert_eq!(ranges, fresh(mb));
            workspace.col_ranges = ranges;
        }

        let mut rnd = oorandom::Rand32::new(4321);
        for _ in 0..4 {
            let mut bodies = RigidBodySet::new();
            let mut joints = MultibodyJointSet::new();
            let handles: Vec<_> = (0..12)
                .map(|_| bodies.insert(RigidBodyBuilder::dynamic()))
                .collect();
            let mut order: Vec<usize> = (1..12).collect();
            let n = order.len() as u32;
            for l in 0..order.len() {
                order.swap(l, rnd.rand_range(0..n) as usize);
            }
            let mut workspace = MultibodyWorkspace::new();
            for i in order {
                // Each body hangs from an earlier one: a tree with forks.
                let parent = handles[rnd.rand_range(0..i as u32) as usize];
                let h = joints.insert(parent, handles[i], joint, true).unwrap();
                let mb = &joints.get(h).unwrap().0;
                let ranges = workspace.column_ranges(&mb.links);
                assert_eq!(ranges, fresh(mb));
                workspace.col_ranges = ranges;
            }
        }
    }
}
