//! Every supported volume in ../shared/data, checked against ../shared/data/README.md (dims,
//! spacing, origin where given, type). Skips with a message when ../shared is absent.

use glam::DVec3;
use test_support::{close, shared_or_skip};
use volume::{FieldSelector, Space};

struct Case {
    file: &'static str,
    dims: [usize; 3],
    spacing: [f64; 3],
    origin: Option<[f64; 3]>,
    ty: &'static str,
    components: usize,
}

const CASES: &[Case] = &[
    Case {
        file: "mri/mni_icbm152_t1_tal_nlin_sym_09a.nii.gz",
        dims: [197, 233, 189],
        spacing: [1.0; 3],
        origin: Some([-98.0, -134.0, -72.0]),
        ty: "uint8",
        components: 1,
    },
    Case {
        file: "mri/mni_icbm152_wm_tal_nlin_sym_09a.nii.gz",
        dims: [197, 233, 189],
        spacing: [1.0; 3],
        origin: Some([-98.0, -134.0, -72.0]),
        ty: "uint8",
        components: 1,
    },
    Case {
        file: "mri/headsq_64x64x93.nhdr",
        dims: [64, 64, 93],
        spacing: [3.2, 3.2, 1.5],
        origin: None,
        ty: "int16",
        components: 1,
    },
    Case {
        file: "mri/HeadMRVolume.mhd",
        dims: [48, 62, 42],
        spacing: [4.0; 3],
        origin: None,
        ty: "uint8",
        components: 1,
    },
    Case {
        file: "volumes/ironProt.vtk",
        dims: [68, 68, 68],
        spacing: [1.0; 3],
        origin: None,
        ty: "uint8",
        components: 1,
    },
    Case {
        file: "volumes/hydrogen.vti",
        dims: [64, 64, 64],
        spacing: [1.0; 3],
        origin: None,
        ty: "float32",
        components: 1,
    },
    Case {
        file: "volumes/neghip.slc",
        dims: [66, 66, 66],
        spacing: [1.0; 3],
        origin: None,
        ty: "uint8",
        components: 1,
    },
    Case {
        file: "volumes/embryo.slc",
        dims: [256, 256, 256],
        spacing: [1.0; 3],
        origin: None,
        ty: "uint8",
        components: 1,
    },
    Case {
        file: "cfd/heart.vti",
        dims: [32, 32, 12],
        spacing: [1.0, 1.0, 4.0],
        origin: None,
        ty: "float32",
        components: 1,
    },
    Case {
        file: "cfd/carotid.vtk",
        dims: [76, 49, 45],
        spacing: [1.0; 3],
        origin: Some([100.0, 80.0, 1.0]),
        ty: "float32",
        components: 1,
    },
    Case {
        file: "dti/FA.nii.gz",
        dims: [84, 92, 56],
        spacing: [2.2; 3],
        origin: None,
        ty: "float32",
        components: 1,
    },
    Case {
        file: "dti/V1.nii.gz",
        dims: [84, 92, 56],
        spacing: [2.2; 3],
        origin: None,
        ty: "float32",
        components: 3,
    },
];

#[test]
fn every_shared_volume_has_the_documented_grid() {
    let Some(data) = shared_or_skip("every_shared_volume_has_the_documented_grid") else {
        return;
    };
    for c in CASES {
        let path = data.join(c.file);
        let vol = volume::load(&path).unwrap_or_else(|e| panic!("{}: {e}", c.file));
        assert_eq!(vol.dims, c.dims, "{}", c.file);
        let sp = vol.spacing();
        for a in 0..3 {
            assert!(
                close(sp[a], c.spacing[a], 1e-6, 1e-6),
                "{}: spacing {sp:?}",
                c.file
            );
        }
        if let Some(o) = c.origin {
            let w = vol.affine.w_axis.truncate();
            assert!(
                (w - DVec3::from(o)).length() < 1e-6,
                "{}: origin {w}",
                c.file
            );
        }
        let f = vol.default();
        assert_eq!(f.stored.name(), c.ty, "{}", c.file);
        assert_eq!(f.components, c.components, "{}", c.file);
        let st = f.stats();
        assert!(st.max > st.min, "{}: constant data {st:?}", c.file);
        assert_eq!(st.nonfinite, 0, "{}", c.file);
    }
}

#[test]
fn mni_template_is_ras_and_centred_on_the_brain() {
    let Some(data) = shared_or_skip("mni_template_is_ras_and_centred_on_the_brain") else {
        return;
    };
    let vol = volume::load(&data.join("mri/mni_icbm152_t1_tal_nlin_sym_09a.nii.gz")).unwrap();
    assert_eq!(vol.space, Space::Ras);
    let [lo, hi] = vol.bounds();
    assert_eq!([lo.x, lo.y, lo.z], [-98.0, -134.0, -72.0]);
    assert_eq!([hi.x, hi.y, hi.z], [98.0, 98.0, 116.0]);
    // The brain is brighter than the background: the voxel at world (0, -18, 18) (white
    // matter near the corpus callosum) is far brighter than the corner.
    let ijk = vol
        .affine
        .inverse()
        .transform_point3(DVec3::new(0.0, -18.0, 18.0))
        .round();
    let centre = vol.default().data[vol.index(ijk.x as usize, ijk.y as usize, ijk.z as usize)];
    assert!(
        centre > 60.0 && vol.default().data[0] < 5.0,
        "centre {centre}, corner {}",
        vol.default().data[0]
    );
}

#[test]
fn carotid_exposes_scalars_and_vectors_by_name() {
    let Some(data) = shared_or_skip("carotid_exposes_scalars_and_vectors_by_name") else {
        return;
    };
    let vol = volume::load(&data.join("cfd/carotid.vtk")).unwrap();
    assert_eq!(vol.field_names(), vec!["scalars", "vectors"]);
    let v = vol
        .select(Some(&"vectors".parse::<FieldSelector>().unwrap()))
        .unwrap();
    assert_eq!(v.components, 3);
    let m = vol
        .select(Some(&"vectors:magnitude".parse::<FieldSelector>().unwrap()))
        .unwrap();
    assert_eq!(m.components, 1);
    let i = 1234;
    let want = (v.data[3 * i] as f64)
        .hypot(v.data[3 * i + 1] as f64)
        .hypot(v.data[3 * i + 2] as f64);
    assert!(close(m.data[i] as f64, want, 1e-6, 1e-9));
    assert!(m.stats().max > 0.0);
}

#[test]
fn dti_principal_eigenvectors_run_left_right_in_the_corpus_callosum() {
    // Verifies that vector components are not permuted by the frame conversion: in the
    // mid-sagittal corpus callosum the fibres run left-right, so V1 in world coordinates must be
    // close to +-x. This subject is not in MNI space: its mid-sagittal plane is voxel i = 41
    // (world x = -4.4) and the callosal arc lies at world y in [-23, 30], z in [-40, -29] (found
    // by plotting FA in that plane).
    let Some(data) =
        shared_or_skip("dti_principal_eigenvectors_run_left_right_in_the_corpus_callosum")
    else {
        return;
    };
    let fa = volume::load(&data.join("dti/FA.nii.gz")).unwrap();
    let v1 = volume::load(&data.join("dti/V1.nii.gz")).unwrap();
    assert_eq!(fa.affine, v1.affine);
    let inv = fa.affine.inverse();
    let (mut n, mut sum_x) = (0, 0.0);
    for y in (-23..=30).step_by(2) {
        for z in (-40..=-29).step_by(1) {
            let ijk = inv
                .transform_point3(DVec3::new(-4.4, y as f64, z as f64))
                .round();
            if ijk.min_element() < 0.0 || ijk.x >= 84.0 || ijk.y >= 92.0 || ijk.z >= 56.0 {
                continue;
            }
            let idx = fa.index(ijk.x as usize, ijk.y as usize, ijk.z as usize);
            if fa.default().data[idx] > 0.5 {
                let v = &v1.default().data[3 * idx..3 * idx + 3];
                let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                sum_x += (v[0] / len).abs() as f64;
                n += 1;
            }
        }
    }
    assert!(n >= 10, "only {n} high-FA mid-sagittal voxels");
    // A permutation of components would put the callosal direction elsewhere (mean about 0.3).
    assert!(
        sum_x / n as f64 > 0.75,
        "mean |V1.x| = {} over {n} voxels",
        sum_x / n as f64
    );
}
