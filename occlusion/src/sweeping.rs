//! Singh, Yuksel and House, "Fast Occlusion Sweeping" (ISVC 2009; `../shared/seeds`): the
//! paper's equation index. The CPU fields live in the `volume` crate (they need only a grid:
//! `&[f32]`, dims and spacing) and are re-exported here, so that someone holding the paper
//! finds every equation from this page.
//!
//! | paper | CPU | GPU (`engine`, `shaders/`) | checked by |
//! |---|---|---|---|
//! | §1.1, eq. 1 (the intended form; the printed one is garbled), Table 1 sweep orders | [`distance::sweep_distance`], [`distance::SWEEP_DIRECTIONS`] | - | `volume/tests/distance_accuracy.rs` (analytic solids, against scipy/edt and scikit-fmm in `docs/accuracy.md`) |
//! | §1.1 "open vertices" (the band next to the surface) and our default in place of the sweeps: the distance to the surface patch of the nearest band voxel by an exact feature transform (not in the paper; fast sweeping stays available as `--distance sweeping`) | [`distance::classify_and_initialise`], [`closest_point::closest_point_distance`] | - | `closest_point` unit tests (against an exhaustive search), `volume/tests/distance_accuracy.rs` (`closest_points_have_no_point_source_error`) |
//! | §2, eq. 6 octant visibility | [`octants::sweep_octants`], [`octants::sweep_fields`] | - | `octants` unit tests (lockstep against the straightforward eq. 6), `tests/tests/occlusion.rs` |
//! | eq. 7 transmittance `tau = clamp(D / h + 1/2, 0, 1)`, `h = h_min`; eq. 8 subsurface (derived, the printed form inverts it) | [`octants::transmittance`] | - | `octants` unit tests |
//! | eq. 7 for a solid cut by clipping planes (not in the paper: the removed half-spaces transparent by the same rule from the distance past each plane, so the octants describe the cut solid; from a distance file, eq. 7-8 on the distance alone) | [`octants::open_cut`], [`octants::fields_from_band_cut`], [`octants::transmittance_from_distance`]; `scene::fields::iso_fields` | - | `octants` unit test `a_cut_opens_the_cavity_it_crosses_to_the_sky_on_its_side`, `scene/tests/iso_render.rs` (`a_cut_opens_the_cavity_behind_it_to_the_sky`, `fields_from_files_keep_their_subsurface_opacity_when_cut`) |
//! | eq. 2, 4-5 `A(P, N) = sum_s V_s(P) G_s(N)`, `G_s` the projected solid angle of the octant clipped by `N` | [`shading::AmbientModel`], [`shading::geometry_term`], [`shading::projected_solid_angle`], [`shading::sample_octants`] | `iso_pass.wgsl::ambient`, `geometry_term`, `projected_solid_angle`, `sample_octants` | `shading` unit tests, `scene/tests/iso_render.rs` (GPU = CPU) |
//! | §3 isosurface rendering with the swept ambient term; Fig. 3-4 ground truth (Monte Carlo AO) | [`crate::isosurface`] | `iso_pass.wgsl::main` | `scene/tests/iso_render.rs`, `tests/tests/occlusion.rs`, `umbra bench sweep` |
//! | §4.2 subsurface variant `|N . w|` | [`shading::GeometryTerm::Absolute`] | `iso_pass.wgsl::geometry_term` | `shading` unit tests |

pub use volume::closest_point;
pub use volume::distance_sweep as distance;
pub use volume::occlusion_shading as shading;
pub use volume::occlusion_sweep as octants;
