#include "rve_server/wire/convert.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace rvehub::wire {
namespace {

using google::protobuf::RepeatedField;

template <typename T>
void Put(const std::vector<T>& v, RepeatedField<T>* out) {
  out->Assign(v.begin(), v.end());
}

template <typename T>
std::vector<T> Take(const RepeatedField<T>& v) {
  return std::vector<T>(v.begin(), v.end());
}

void Put2(const Eigen::Matrix2d& m, RepeatedField<double>* out) {
  out->Clear();
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) out->Add(m(r, c));
}

absl::StatusOr<Eigen::Matrix2d> Take2(const RepeatedField<double>& v, absl::string_view field) {
  if (v.size() != 4) {
    return absl::InvalidArgumentError(
        absl::StrCat("packing.", field, " must have 4 values (2×2 row-major), got ", v.size()));
  }
  Eigen::Matrix2d m;
  m << v[0], v[1], v[2], v[3];
  return m;
}

}  // namespace

void ToProto(const Eigen::Matrix3d& m, RepeatedField<double>* out) {
  out->Clear();
  out->Reserve(9);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out->Add(m(r, c));
}

absl::StatusOr<Eigen::Matrix3d> Matrix3FromProto(const RepeatedField<double>& v,
                                                 absl::string_view field) {
  if (v.size() != 9) {
    return absl::InvalidArgumentError(
        absl::StrCat(field, " must have 9 values (3×3 row-major), got ", v.size()));
  }
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = v[3 * r + c];
  return m;
}

void ToProto(const dem::Material& m, v1::Material* out) {
  out->set_name(m.name);
  out->set_density(m.density);
  out->set_young_modulus(m.young_modulus);
  out->set_stiffness_ratio(m.stiffness_ratio);
  out->set_poisson_ratio(m.poisson_ratio);
  out->set_friction(m.friction);
  out->set_rolling_beta(m.rolling_beta);
  out->set_rolling_eta(m.rolling_eta);
  out->set_bond_cohesion(m.bond_cohesion);
  out->set_damping(m.damping);
  out->set_thickness(m.thickness);
  out->set_model(m.model == dem::ContactModel::kHertzMindlin ? v1::CONTACT_MODEL_HERTZ_MINDLIN
                                                             : v1::CONTACT_MODEL_LINEAR);
}

dem::Material FromProto(const v1::Material& m) {
  dem::Material out;
  out.name = m.name();
  out.density = m.density();
  out.young_modulus = m.young_modulus();
  out.stiffness_ratio = m.stiffness_ratio();
  out.poisson_ratio = m.poisson_ratio();
  out.friction = m.friction();
  out.rolling_beta = m.rolling_beta();
  out.rolling_eta = m.rolling_eta();
  out.bond_cohesion = m.bond_cohesion();
  out.damping = m.damping();
  out.thickness = m.thickness();
  out.model = m.model() == v1::CONTACT_MODEL_HERTZ_MINDLIN ? dem::ContactModel::kHertzMindlin
                                                           : dem::ContactModel::kLinear;
  return out;
}

void ToProto(const dem::Controls& c, v1::Controls* out) {
  out->set_time_step_factor(c.time_step_factor);
  out->set_max_inertial_number(c.max_inertial_number);
  out->set_pressure_floor(c.pressure_floor);
  out->set_min_steps(c.min_steps);
  out->set_max_stretch(c.max_stretch);
  out->set_max_rotation(c.max_rotation);
  out->set_mass_scale(c.mass_scale);
  out->set_skin(c.skin);
}

dem::Controls FromProto(const v1::Controls& c) {
  dem::Controls out;
  out.time_step_factor = c.time_step_factor();
  out.max_inertial_number = c.max_inertial_number();
  out.pressure_floor = c.pressure_floor();
  out.min_steps = c.min_steps();
  out.max_stretch = c.max_stretch();
  out.max_rotation = c.max_rotation();
  out.mass_scale = c.mass_scale();
  out.skin = c.skin();
  return out;
}

void ToProto(const dem::RveSnapshot& p, v1::Packing* out) {
  ToProto(p.material, out->mutable_material());
  ToProto(p.controls, out->mutable_controls());
  Put2(p.cell, out->mutable_cell());
  Put2(p.reference_cell, out->mutable_reference_cell());
  Put2(p.frame, out->mutable_frame());
  Put(p.radius, out->mutable_radius());
  Put(p.sx, out->mutable_sx());
  Put(p.sy, out->mutable_sy());
  Put(p.vx, out->mutable_vx());
  Put(p.vy, out->mutable_vy());
  Put(p.omega, out->mutable_omega());
  Put(p.theta, out->mutable_theta());
  const int nc = static_cast<int>(p.contacts.size());
  out->mutable_contact_i()->Reserve(nc);
  out->mutable_contact_j()->Reserve(nc);
  out->mutable_contact_tangential_force()->Reserve(nc);
  out->mutable_contact_rolling_moment()->Reserve(nc);
  out->mutable_contact_bond_strength()->Reserve(nc);
  for (const dem::ContactHistory& c : p.contacts) {
    out->add_contact_i(c.i);
    out->add_contact_j(c.j);
    out->add_contact_tangential_force(c.tangential_force);
    out->add_contact_rolling_moment(c.rolling_moment);
    out->add_contact_bond_strength(c.bond_strength);
  }
  out->set_initial_void_ratio(p.initial_void_ratio);
  out->set_permeability_coefficient(p.permeability_coefficient);
  out->set_total_steps(p.total_steps);
}

absl::StatusOr<dem::RveSnapshot> FromProto(const v1::Packing& p) {
  if (!p.has_material()) return absl::InvalidArgumentError("packing.material is missing");
  if (!p.has_controls()) return absl::InvalidArgumentError("packing.controls is missing");
  dem::RveSnapshot out;
  out.material = FromProto(p.material());
  out.controls = FromProto(p.controls());
  absl::StatusOr<Eigen::Matrix2d> cell = Take2(p.cell(), "cell");
  if (!cell.ok()) return cell.status();
  absl::StatusOr<Eigen::Matrix2d> ref = Take2(p.reference_cell(), "reference_cell");
  if (!ref.ok()) return ref.status();
  absl::StatusOr<Eigen::Matrix2d> frame = Take2(p.frame(), "frame");
  if (!frame.ok()) return frame.status();
  out.cell = *cell;
  out.reference_cell = *ref;
  out.frame = *frame;
  const int n = p.radius_size();
  const std::pair<const char*, int> particle_arrays[] = {
      {"sx", p.sx_size()}, {"sy", p.sy_size()},       {"vx", p.vx_size()},
      {"vy", p.vy_size()}, {"omega", p.omega_size()}, {"theta", p.theta_size()}};
  for (const auto& [name, size] : particle_arrays) {
    if (size != n) {
      return absl::InvalidArgumentError(
          absl::StrCat("packing.", name, " has ", size, " values but packing.radius has ", n));
    }
  }
  const int nc = p.contact_i_size();
  const std::pair<const char*, int> contact_arrays[] = {
      {"contact_j", p.contact_j_size()},
      {"contact_tangential_force", p.contact_tangential_force_size()},
      {"contact_rolling_moment", p.contact_rolling_moment_size()},
      {"contact_bond_strength", p.contact_bond_strength_size()}};
  for (const auto& [name, size] : contact_arrays) {
    if (size != nc) {
      return absl::InvalidArgumentError(
          absl::StrCat("packing.", name, " has ", size, " values but packing.contact_i has ", nc));
    }
  }
  out.radius = Take(p.radius());
  out.sx = Take(p.sx());
  out.sy = Take(p.sy());
  out.vx = Take(p.vx());
  out.vy = Take(p.vy());
  out.omega = Take(p.omega());
  out.theta = Take(p.theta());
  out.contacts.resize(nc);
  for (int k = 0; k < nc; ++k) {
    out.contacts[k] = {p.contact_i(k), p.contact_j(k), p.contact_tangential_force(k),
                       p.contact_rolling_moment(k), p.contact_bond_strength(k)};
  }
  out.initial_void_ratio = p.initial_void_ratio();
  out.permeability_coefficient = p.permeability_coefficient();
  out.total_steps = p.total_steps();
  return out;
}

void ToProto(const RveRecord& r, v1::RveRecord* out) {
  out->set_run_id(r.run_id);
  out->set_id(r.id);
  out->set_step(r.step);
  ToProto(r.last_delta_f, out->mutable_last_delta_f());
  ToProto(r.packing, out->mutable_packing());
}

absl::StatusOr<RveRecord> FromProto(const v1::RveRecord& r) {
  RveRecord out;
  out.run_id = r.run_id();
  out.id = r.id();
  out.step = r.step();
  absl::StatusOr<Eigen::Matrix3d> f = Matrix3FromProto(r.last_delta_f(), "last_delta_f");
  if (!f.ok()) return f.status();
  out.last_delta_f = *f;
  absl::StatusOr<dem::RveSnapshot> p = FromProto(r.packing());
  if (!p.ok()) return p.status();
  out.packing = *std::move(p);
  return out;
}

void ToProto(const dem::RveState& s, const Eigen::Matrix3d& deformation_gradient,
             v1::RveState* out) {
  ToProto(s.stress, out->mutable_stress());
  ToProto(s.fabric, out->mutable_fabric());
  ToProto(s.fabric_anisotropy_tensor, out->mutable_fabric_anisotropy_tensor());
  out->set_fabric_anisotropy(s.fabric_anisotropy);
  out->set_fabric_defined(s.fabric_defined);
  out->set_void_ratio(s.void_ratio);
  out->set_porosity(s.porosity);
  out->set_coordination(s.coordination);
  out->set_mechanical_coordination(s.mechanical_coordination);
  out->set_permeability(s.permeability);
  out->set_mean_rotation(s.mean_rotation);
  out->set_kinetic_energy(s.kinetic_energy);
  out->set_unbalanced_force_ratio(s.unbalanced_force_ratio);
  out->set_num_contacts(s.num_contacts);
  out->set_volume(s.volume);
  out->set_steps(s.steps);
  out->set_time_step(s.time_step);
  out->set_mass_scale(s.mass_scale);
  out->set_mean_pressure(s.MeanPressure());
  out->set_deviator_stress(s.DeviatorStress());
  ToProto(deformation_gradient, out->mutable_deformation_gradient());
  if (s.tangent) {
    RepeatedField<double>* t = out->mutable_tangent();
    t->Reserve(81);
    for (int r = 0; r < 9; ++r)
      for (int c = 0; c < 9; ++c) t->Add((*s.tangent)(r, c));
  }
}

void ToProto(const RveOutcome& o, v1::RveResult* out) {
  out->set_id(o.id);
  out->set_code(static_cast<int>(o.status.code()));
  out->set_step(o.step);
  out->set_engine_seconds(o.engine_seconds);
  if (o.status.ok()) {
    ToProto(o.state, o.deformation_gradient, out->mutable_state());
  } else {
    out->set_message(std::string(o.status.message().substr(0, kMaxResultMessageBytes)));
  }
}

void ToProto(const TemplateInfo& t, v1::TemplateInfo* out) {
  out->set_name(t.name);
  out->set_description(t.description);
  out->set_material_name(t.material_name);
  out->set_num_particles(t.num_particles);
  out->set_void_ratio(t.void_ratio);
  out->set_mean_pressure(t.mean_pressure);
}

TemplateInfo FromProto(const v1::TemplateInfo& t) {
  TemplateInfo out;
  out.name = t.name();
  out.description = t.description();
  out.material_name = t.material_name();
  out.num_particles = t.num_particles();
  out.void_ratio = t.void_ratio();
  out.mean_pressure = t.mean_pressure();
  return out;
}

void ToProto(const RunInfo& r, v1::RunInfo* out) {
  out->set_run_id(r.run_id);
  out->set_num_rves(r.num_rves);
  out->set_min_step(r.min_step);
  out->set_max_step(r.max_step);
}

RunInfo FromProto(const v1::RunInfo& r) {
  return {r.run_id(), r.num_rves(), r.min_step(), r.max_step()};
}

void ToProto(const dem::ApplyOptions& o, v1::ApplyOptions* out) {
  out->set_want_tangent(o.want_tangent);
  out->set_max_inertial_number(o.max_inertial_number);
  out->set_relax(o.relax);
  out->set_relax_tolerance(o.relax_tolerance);
  out->set_relax_max_steps(o.relax_max_steps);
  out->set_duration(o.duration);
  out->set_stress_only(o.stress_only);
}

dem::ApplyOptions FromProto(const v1::ApplyOptions& o) {
  // Zero means "the default"; the registry checks the values.
  dem::ApplyOptions out;
  out.want_tangent = o.want_tangent();
  out.relax = o.relax();
  if (o.max_inertial_number() != 0) out.max_inertial_number = o.max_inertial_number();
  if (o.relax_tolerance() != 0) out.relax_tolerance = o.relax_tolerance();
  if (o.relax_max_steps() != 0) out.relax_max_steps = o.relax_max_steps();
  out.duration = o.duration();
  out.stress_only = o.stress_only();
  return out;
}

v1::ApplyMode ToProto(ApplyMode mode) {
  return mode == ApplyMode::kTrial ? v1::APPLY_MODE_TRIAL : v1::APPLY_MODE_COMMIT;
}

absl::StatusOr<ApplyMode> FromProto(v1::ApplyMode mode) {
  switch (mode) {
    case v1::APPLY_MODE_COMMIT:
      return ApplyMode::kCommit;
    case v1::APPLY_MODE_TRIAL:
      return ApplyMode::kTrial;
    default:
      return absl::InvalidArgumentError("mode must be APPLY_MODE_COMMIT or APPLY_MODE_TRIAL");
  }
}

absl::StatusOr<std::vector<Increment>> FromProto(
    const google::protobuf::RepeatedPtrField<v1::Increment>& increments) {
  std::vector<Increment> out(increments.size());
  for (int k = 0; k < increments.size(); ++k) {
    const v1::Increment& inc = increments[k];
    absl::StatusOr<Eigen::Matrix3d> f = Matrix3FromProto(
        inc.delta_f(), absl::StrCat("increments[", k, "] (id ", inc.id(), ").delta_f"));
    if (!f.ok()) return f.status();
    out[k] = {inc.id(), *f};
  }
  return out;
}

absl::StatusOr<InitialStress> FromProto(const v1::InitialStress& s) {
  InitialStress out;
  switch (s.kind_case()) {
    case v1::InitialStress::kPressure:
      out.kind = InitialStress::Kind::kIsotropic;
      out.pressure = s.pressure();
      return out;
    case v1::InitialStress::kK0:
      out.kind = InitialStress::Kind::kK0;
      out.vertical_compression = s.k0().vertical_compression();
      out.k0 = s.k0().k0();
      return out;
    default:
      return absl::InvalidArgumentError("an initial stress names neither pressure nor k0");
  }
}

void ToProto(const InitialStress& s, v1::InitialStress* out) {
  switch (s.kind) {
    case InitialStress::Kind::kTemplate:
      break;
    case InitialStress::Kind::kIsotropic:
      out->set_pressure(s.pressure);
      break;
    case InitialStress::Kind::kK0:
      out->mutable_k0()->set_vertical_compression(s.vertical_compression);
      out->mutable_k0()->set_k0(s.k0);
      break;
  }
}

absl::Status FromProto(const v1::RveResult& r, RveOutcome* out) {
  out->id = r.id();
  out->step = r.step();
  out->engine_seconds = std::isfinite(r.engine_seconds()) ? r.engine_seconds() : 0.0;
  if (r.code() != 0) {
    out->status = absl::Status(static_cast<absl::StatusCode>(r.code()), r.message());
    return absl::OkStatus();
  }
  out->status = absl::OkStatus();
  return FromProto(r.state(), &out->state, &out->deformation_gradient);
}

absl::StatusOr<dem::ElementTestSpec> FromProto(const v1::ElementTestRequest& r) {
  dem::ElementTestSpec s;
  switch (r.test()) {
    case v1::ELEMENT_TEST_DRAINED_BIAXIAL:
      s.kind = dem::ElementTestKind::kDrainedBiaxial;
      break;
    case v1::ELEMENT_TEST_ISOTROPIC:
      s.kind = dem::ElementTestKind::kIsotropic;
      break;
    case v1::ELEMENT_TEST_OEDOMETER:
      s.kind = dem::ElementTestKind::kOedometer;
      break;
    case v1::ELEMENT_TEST_UNDRAINED_SIMPLE_SHEAR:
      s.kind = dem::ElementTestKind::kUndrainedSimpleShear;
      break;
    case v1::ELEMENT_TEST_CYCLIC_SIMPLE_SHEAR:
      s.kind = dem::ElementTestKind::kCyclicSimpleShear;
      break;
    default:
      return absl::InvalidArgumentError(
          absl::StrCat("test must name an element test, got ", static_cast<int>(r.test())));
  }
  // Zero means "the engine's default" for every numeric field.
  if (r.confining_pressure() != 0) s.confining = r.confining_pressure();
  if (r.max_strain() != 0) s.max_strain = r.max_strain();
  if (r.inertial_number() != 0) s.inertial_number = r.inertial_number();
  if (r.rows() != 0) s.rows = r.rows();
  s.cyclic_control =
      r.cyclic_stress_control() ? dem::CyclicControl::kStress : dem::CyclicControl::kStrain;
  if (r.amplitude() != 0) s.amplitude = r.amplitude();
  if (r.cycles() != 0) s.cycles = r.cycles();
  switch (r.axis()) {
    case v1::LOADING_AXIS_UNSPECIFIED:
    case v1::LOADING_AXIS_Y:
      s.axis = 1;
      break;
    case v1::LOADING_AXIS_X:
      s.axis = 0;
      break;
    case v1::LOADING_AXIS_Z:
      return absl::InvalidArgumentError("axis z needs a 3-D RVE; these are 2-D (x or y)");
    default:
      return absl::InvalidArgumentError(
          absl::StrCat("axis must name a loading axis, got ", static_cast<int>(r.axis())));
  }
  return s;
}

void ToProto(const dem::ElementTestRow& r, v1::ElementTestRow* out) {
  out->set_step(r.step);
  out->set_axial_strain(r.axial_strain_comp);
  out->set_vol_strain(r.vol_strain_comp);
  out->set_sxx(r.sxx_comp);
  out->set_syy(r.syy_comp);
  out->set_sxy(r.sxy_comp);
  out->set_p(r.p_comp);
  out->set_q(r.q);
  out->set_void_ratio(r.void_ratio);
  out->set_coordination(r.coordination);
  out->set_fabric_xx(r.fabric_xx);
  out->set_fabric_yy(r.fabric_yy);
  out->set_fabric_xy(r.fabric_xy);
  out->set_fabric_anisotropy(r.fabric_anisotropy);
  out->set_permeability(r.permeability);
  out->set_shear_strain(r.shear_strain);
}

dem::ElementTestRow FromProto(const v1::ElementTestRow& r) {
  dem::ElementTestRow out;
  out.step = r.step();
  out.axial_strain_comp = r.axial_strain();
  out.vol_strain_comp = r.vol_strain();
  out.sxx_comp = r.sxx();
  out.syy_comp = r.syy();
  out.sxy_comp = r.sxy();
  out.p_comp = r.p();
  out.q = r.q();
  out.void_ratio = r.void_ratio();
  out.coordination = r.coordination();
  out.fabric_xx = r.fabric_xx();
  out.fabric_yy = r.fabric_yy();
  out.fabric_xy = r.fabric_xy();
  out.fabric_anisotropy = r.fabric_anisotropy();
  out.permeability = r.permeability();
  out.shear_strain = r.shear_strain();
  return out;
}

v1::ElementTest ToProto(dem::ElementTestKind kind) {
  switch (kind) {
    case dem::ElementTestKind::kDrainedBiaxial:
      return v1::ELEMENT_TEST_DRAINED_BIAXIAL;
    case dem::ElementTestKind::kIsotropic:
      return v1::ELEMENT_TEST_ISOTROPIC;
    case dem::ElementTestKind::kOedometer:
      return v1::ELEMENT_TEST_OEDOMETER;
    case dem::ElementTestKind::kUndrainedSimpleShear:
      return v1::ELEMENT_TEST_UNDRAINED_SIMPLE_SHEAR;
    case dem::ElementTestKind::kCyclicSimpleShear:
      return v1::ELEMENT_TEST_CYCLIC_SIMPLE_SHEAR;
  }
  return v1::ELEMENT_TEST_UNSPECIFIED;
}

void ToProto(const dem::ElementTestSpec& s, v1::ElementTestRequest* out) {
  out->set_test(ToProto(s.kind));
  out->set_confining_pressure(s.confining);
  out->set_max_strain(s.max_strain);
  out->set_inertial_number(s.inertial_number);
  out->set_rows(s.rows);
  out->set_cyclic_stress_control(s.cyclic_control == dem::CyclicControl::kStress);
  out->set_amplitude(s.amplitude);
  out->set_cycles(s.cycles);
  out->set_axis(s.axis == 0 ? v1::LOADING_AXIS_X : v1::LOADING_AXIS_Y);
}

absl::Status FromProto(const v1::RveState& s, dem::RveState* out,
                       Eigen::Matrix3d* deformation_gradient) {
  const std::pair<const RepeatedField<double>*, Eigen::Matrix3d*> tensors[] = {
      {&s.stress(), &out->stress},
      {&s.fabric(), &out->fabric},
      {&s.fabric_anisotropy_tensor(), &out->fabric_anisotropy_tensor},
      {&s.deformation_gradient(), deformation_gradient}};
  for (const auto& [field, m] : tensors) {
    absl::StatusOr<Eigen::Matrix3d> v = Matrix3FromProto(*field, "state tensor");
    if (!v.ok()) return v.status();
    *m = *v;
  }
  out->fabric_anisotropy = s.fabric_anisotropy();
  out->fabric_defined = s.fabric_defined();
  out->void_ratio = s.void_ratio();
  out->porosity = s.porosity();
  out->coordination = s.coordination();
  out->mechanical_coordination = s.mechanical_coordination();
  out->permeability = s.permeability();
  out->mean_rotation = s.mean_rotation();
  out->kinetic_energy = s.kinetic_energy();
  out->unbalanced_force_ratio = s.unbalanced_force_ratio();
  out->num_contacts = s.num_contacts();
  out->volume = s.volume();
  out->steps = s.steps();
  out->time_step = s.time_step();
  out->mass_scale = s.mass_scale();
  out->tangent.reset();
  if (s.tangent_size() == 81) {
    Eigen::Matrix<double, 9, 9>& tangent = out->tangent.emplace();
    for (int r = 0; r < 9; ++r)
      for (int c = 0; c < 9; ++c) tangent(r, c) = s.tangent(9 * r + c);
  } else if (s.tangent_size() != 0) {
    return absl::DataLossError(absl::StrCat("tangent has ", s.tangent_size(), " values, not 81"));
  }
  return absl::OkStatus();
}

}  // namespace rvehub::wire
