//! The data in datasets/ read as documented in datasets/LICENSES.md (no ../shared needed).

use test_support::root;
use volume::Space;

#[test]
fn bundled_volumes_read_with_their_documented_grids() {
    let d = root().join("datasets");
    let t1 = volume::load(&d.join("mni/mni_icbm152_t1_tal_nlin_sym_09a.nii.gz")).unwrap();
    assert_eq!(t1.dims, [197, 233, 189]);
    assert_eq!(t1.space, Space::Ras);
    assert_eq!(
        t1.affine.w_axis.truncate().to_array(),
        [-98.0, -134.0, -72.0]
    );
    let wm = volume::load(&d.join("mni/mni_icbm152_wm_tal_nlin_sym_09a.nii.gz")).unwrap();
    assert_eq!(wm.affine, t1.affine);
    let ct = volume::load(&d.join("vtk/headsq_64x64x93.nhdr")).unwrap();
    assert_eq!(ct.dims, [64, 64, 93]);
    assert_eq!(ct.spacing(), [3.2, 3.2, 1.5]);
    let car = volume::load(&d.join("vtk/carotid.vtk")).unwrap();
    assert_eq!(car.dims, [76, 49, 45]);
    assert_eq!(car.field_names(), vec!["scalars", "vectors"]);
    for f in ["mni/NOTICE.txt", "vtk/VTKDATA-COPYRIGHT.txt", "LICENSES.md"] {
        assert!(d.join(f).is_file(), "{f} missing");
    }
}
