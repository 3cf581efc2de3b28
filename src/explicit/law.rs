//! Contact laws of the explicit driver, behind one small trait ([`ContactModel`]).
//!
//! A law is a pure function of the pair's geometry ([`PairGeom`]) and its own per-contact `Copy`
//! state (docs/design.md, "Data and dispatch"): the elastic laws here carry no state (`()`);
//! Luding's and the SinterNormal laws (docs/luding.md, docs/frenkel.md) will carry δ_max, δ_0, δ_p.
//! The driver is generic over the law (static dispatch); the case's choice is an enum
//! ([`NormalLaw`]) matched once when the driver is built.
//!
//! Sign conventions (docs/luding.md, "Notation and signs"): overlap `δ = r_i + r_j − |x_i − x_j|`
//! (> 0 in contact), overlap rate `δ̇ = −(v_i − v_j)·n` (> 0 while approaching), normal force
//! positive when repulsive.

/// What a law sees of one contact at one instant.
#[derive(Debug, Clone, Copy)]
pub struct PairGeom {
    /// Overlap δ [m] (> 0 in contact).
    pub overlap: f64,
    /// Overlap rate δ̇ [m/s] (> 0 while approaching).
    pub overlap_rate: f64,
    /// Reduced mass m_ij = m_i m_j/(m_i + m_j) [kg] (m_i against a wall).
    pub mass: f64,
    /// Reduced radius R_red = r_i r_j/(r_i + r_j) [m] (r_i against a wall).
    pub radius: f64,
}

/// A law's answer for one contact.
#[derive(Debug, Clone, Copy, Default)]
pub struct NormalOut {
    /// Total normal force, elastic + viscous, positive when repulsive [N].
    pub force: f64,
    /// Viscous part of `force` [N] (its power `f_d·δ̇` is dissipated).
    pub damping_force: f64,
    /// Elastic energy stored in the normal spring [J].
    pub elastic_energy: f64,
    /// Tangent normal stiffness dF_el/dδ [N/m], the base of the tangential spring k_t = α·k_n.
    pub stiffness: f64,
    /// Normal damping coefficient at this state [kg/s], the base of γ_t = β·γ_n.
    pub damping: f64,
}

/// A normal contact law with its per-contact state.
pub trait ContactModel: Sync + Send {
    /// Per-contact history (δ_max, δ_p, ... for the sintering laws; `()` for elastic laws).
    type State: Copy + Default + Send + Sync + std::fmt::Debug;
    /// Normal force for a contact with `g.overlap > 0`; may update `state`.
    fn normal(&self, g: &PairGeom, state: &mut Self::State) -> NormalOut;
    /// Duration of a binary collision (half-period of the contact oscillation) t_c [s] for reduced
    /// mass `mass` and reduced radius `radius`; `impact_speed` [m/s] matters only for laws whose
    /// stiffness grows with overlap (Hertz). The time step is a fraction of the smallest t_c.
    fn collision_time(&self, mass: f64, radius: f64, impact_speed: f64) -> f64;

    /// The full particle–particle contact step: normal and tangential force at the contact
    /// described by `c`, updating the law's `state` and the driver's tangential spring `xi`.
    ///
    /// The default is the elastic laws' path: [`Self::normal`], then the driver's Coulomb-limited
    /// spring (`|f_t| ≤ μ·max(f_n, 0)`, `k_t = α·k_n`, `γ_t = β·γ_n`, module docs of
    /// [`crate::explicit`]). The sintering laws ([`crate::explicit::sinter`]) override it: they
    /// need the contact temperature and time step (Luding eqs. 10–12, the SinterNormal rate) and
    /// have their own tangential rule (Luding eqs. 14–24). Particle–wall contacts always use
    /// [`Self::normal`] with a fresh state.
    #[inline]
    fn contact(&self, c: &ContactCtx, state: &mut Self::State, xi: &mut nalgebra::Vector3<f64>, t: &TangentialParams) -> ContactOut {
        let no = self.normal(&c.geom, state);
        let (ft, el_t, diss_t) = super::tangential(xi, &c.normal, &c.tangential_velocity, &no, t.friction, t.stiffness_ratio, t.damping_ratio, t.dt);
        ContactOut {
            normal_force: no.force,
            tangential: ft,
            elastic_energy: no.elastic_energy + el_t,
            dissipation: no.damping_force * c.geom.overlap_rate + diss_t,
        }
    }
}

/// Everything the driver knows about one particle–particle contact at one step
/// ([`ContactModel::contact`]).
#[derive(Debug, Clone, Copy)]
pub struct ContactCtx {
    /// Overlap, rate, reduced mass and radius.
    pub geom: PairGeom,
    /// Unit normal n from j to i.
    pub normal: nalgebra::Vector3<f64>,
    /// Relative surface velocity `v_ij = v_i − v_j + r_i n×ω_i + r_j n×ω_j` [m/s] (Luding eq. 18).
    pub surface_velocity: nalgebra::Vector3<f64>,
    /// Its tangential part `v_ij − n(n·v_ij)` [m/s] (eq. 17).
    pub tangential_velocity: nalgebra::Vector3<f64>,
    /// Radii r_i, r_j [m].
    pub radius_i: f64,
    pub radius_j: f64,
    /// Particle temperatures T_i, T_j [K] (`Particles::temperature`).
    pub temperature_i: f64,
    pub temperature_j: f64,
}

/// The driver's tangential settings, passed to [`ContactModel::contact`].
#[derive(Debug, Clone, Copy)]
pub struct TangentialParams {
    /// Coulomb coefficient μ [1] (`Settings::friction`).
    pub friction: f64,
    /// α = k_t/k_n [1].
    pub stiffness_ratio: f64,
    /// β = γ_t/γ_n [1].
    pub damping_ratio: f64,
    /// Time step Δt [s].
    pub dt: f64,
}

/// A contact's answer to the driver ([`ContactModel::contact`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct ContactOut {
    /// Normal force on i along +n [N], positive repulsive (damping and adhesion included).
    pub normal_force: f64,
    /// Tangential force on i [N] (on j its negative; torques `−r n × f_t`).
    pub tangential: nalgebra::Vector3<f64>,
    /// Elastic energy stored in the contact [J].
    pub elastic_energy: f64,
    /// Dissipated power [W] that the driver accounts for (viscous and sliding).
    pub dissipation: f64,
}

/// How the normal viscous damping of the linear law is given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Damping {
    /// A fixed coefficient γ_n [kg/s].
    Coefficient(f64),
    /// A restitution coefficient e ∈ (0, 1]; γ_n is computed per pair from its reduced mass so
    /// that every binary collision has exactly this e (see [`LinearSpringDashpot::gamma`]).
    Restitution(f64),
    /// γ_n = c·√(m k_n) with the pair's reduced mass m: [`Damping::restitution_ratio`] turns a
    /// restitution coefficient into this form once, so the hot loop evaluates no logarithm per pair
    /// (same γ_n, bit for bit, as `Restitution(e)`).
    Ratio(f64),
}

impl Damping {
    /// `Ratio(c)` with `c = −2 ln e/√(π² + ln² e)`: the same damping as `Restitution(e)`.
    pub fn restitution_ratio(e: f64) -> Damping {
        Damping::Ratio(restitution_factor(e))
    }
}

/// Linear spring-dashpot: `f = k_n δ + γ_n δ̇` (Luding 2005 eq. 4 loading branch with k1 = k2,
/// plus eq. 5). The force is not clipped at zero: the analytic restitution coefficient
/// `e = exp(−η t_c)`, `η = γ_n/(2m)`, `t_c = π/√(k_n/m − η²)` (eq. 6) holds for a contact that ends
/// when δ returns to zero.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearSpringDashpot {
    /// Normal stiffness k_n [N/m].
    pub stiffness: f64,
    /// Normal viscous damping.
    pub damping: Damping,
}

/// `−2 ln e/√(π² + ln² e)`: γ_n = this · √(m k_n) gives restitution e.
#[inline]
fn restitution_factor(e: f64) -> f64 {
    let l = e.ln();
    -2.0 * l / (std::f64::consts::PI.powi(2) + l * l).sqrt()
}

impl LinearSpringDashpot {
    /// γ_n [kg/s] for reduced mass `m` [kg]: for a restitution e,
    /// `γ = −2 ln(e) √(m k)/√(π² + ln² e)` (inverts e = exp(−η π/ω), ω² = k/m − η²).
    #[inline]
    pub fn gamma(&self, m: f64) -> f64 {
        match self.damping {
            Damping::Coefficient(g) => g,
            Damping::Restitution(e) => restitution_factor(e) * (m * self.stiffness).sqrt(),
            Damping::Ratio(c) => c * (m * self.stiffness).sqrt(),
        }
    }

    /// Analytic restitution coefficient of a binary collision with reduced mass `m` [kg]
    /// (Luding 2005 eq. 6): `e = exp(−η t_c)`; 0 when overdamped.
    pub fn restitution(&self, m: f64) -> f64 {
        let eta = self.gamma(m) / (2.0 * m);
        let w2 = self.stiffness / m - eta * eta;
        if w2 <= 0.0 {
            return 0.0;
        }
        (-eta * std::f64::consts::PI / w2.sqrt()).exp()
    }
}

impl ContactModel for LinearSpringDashpot {
    type State = ();
    #[inline]
    fn normal(&self, g: &PairGeom, _: &mut ()) -> NormalOut {
        let gamma = self.gamma(g.mass);
        let fd = gamma * g.overlap_rate;
        NormalOut {
            force: self.stiffness * g.overlap + fd,
            damping_force: fd,
            elastic_energy: 0.5 * self.stiffness * g.overlap * g.overlap,
            stiffness: self.stiffness,
            damping: gamma,
        }
    }
    fn collision_time(&self, mass: f64, _radius: f64, _v: f64) -> f64 {
        let eta = self.gamma(mass) / (2.0 * mass);
        let w2 = self.stiffness / mass - eta * eta;
        if w2 > 0.0 { std::f64::consts::PI / w2.sqrt() } else { std::f64::consts::PI * (mass / self.stiffness).sqrt() }
    }
}

/// Hertzian elastic repulsion with Tsuji-type damping:
/// `f = K δ^{3/2} + β √(m K) δ^{1/4} δ̇`, `K = (4/3) E* √R_red` (Hertz), elastic energy
/// `(2/5) K δ^{5/2}`. With this damping form the restitution coefficient is independent of the
/// impact speed (Tsuji et al. 1992); β = 0 is purely elastic.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hertz {
    /// Effective modulus E* = E/(2(1 − ν²)) for two equal materials [Pa].
    pub effective_modulus: f64,
    /// Dimensionless damping β ≥ 0.
    pub damping: f64,
}

impl ContactModel for Hertz {
    type State = ();
    #[inline]
    fn normal(&self, g: &PairGeom, _: &mut ()) -> NormalOut {
        let k = 4.0 / 3.0 * self.effective_modulus * g.radius.sqrt();
        let sd = g.overlap.sqrt();
        let fe = k * g.overlap * sd;
        let gamma = self.damping * (g.mass * k).sqrt() * sd.sqrt();
        let fd = gamma * g.overlap_rate;
        NormalOut { force: fe + fd, damping_force: fd, elastic_energy: 0.4 * k * g.overlap * g.overlap * sd, stiffness: 1.5 * k * sd, damping: gamma }
    }
    /// Elastic Hertz collision time `t_c = 2.94 (m²/(K² v))^{1/5}` (Johnson 1985, §11.4:
    /// `t_c = 2.94 δ_max/v`, `δ_max = (15 m v²/(16 E* √R))^{2/5}`).
    fn collision_time(&self, mass: f64, radius: f64, v: f64) -> f64 {
        let v = v.max(f64::MIN_POSITIVE);
        let dmax = (15.0 * mass * v * v / (16.0 * self.effective_modulus * radius.sqrt())).powf(0.4);
        2.94 * dmax / v
    }
}

/// The case's choice of elastic law: matched once to build a driver generic over the law.
/// The sintering laws are [`crate::explicit::sinter::LudingLaw`] and
/// [`crate::explicit::sinter::FrenkelLaw`] (case kind `explicit_sinter`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NormalLaw {
    Linear(LinearSpringDashpot),
    Hertz(Hertz),
}
