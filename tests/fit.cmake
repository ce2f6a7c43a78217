# Tests of fit/ (libipsfit) owned by the fit core.
ipsd_add_test(test_airy ipsfit PkgConfig::JANSSON)
ipsd_add_test(test_box ipsfit PkgConfig::JANSSON)
ipsd_add_test(test_design ipsfit)
set_tests_properties(test_design PROPERTIES TIMEOUT 150) # busy, ASan: 36 s (optimised 18 s); 4x
ipsd_add_test(test_model ipsfit PkgConfig::JANSSON)
ipsd_add_test(test_solve ipsfit) # the LAPACK least squares against independent computations
ipsd_add_test(test_pipeline ipsfit PkgConfig::JANSSON)
ipsd_add_test(test_recommend ipsfit PkgConfig::JANSSON)
set_tests_properties(test_recommend PROPERTIES TIMEOUT 120) # 162 refits with box integrals
ipsd_add_test(test_shrink ipsfit) # the shrunk map against analytic cases
ipsd_add_test(test_krige ipsfit) # the kriged map on box-integral scans of known truths
set_tests_properties(test_krige PROPERTIES TIMEOUT 120) # 24 x 24 box integrals per point
ipsd_add_test(test_geometry ipsfit)
set_tests_properties(test_geometry PROPERTIES TIMEOUT 60) # busy, optimised: 3.5 s; ASan ~4x
ipsd_add_test(test_ptc ipsfit) # photon transfer (EMVA 1288) against analytic cases
# fits on threads (ipsd's workers, the sweep's r) equal one thread's, bit for bit: 25 sweeps of a
# 1681-point raster to r = 12
ipsd_add_test(test_fit_threads ipsfit Threads::Threads)
set_tests_properties(test_fit_threads PROPERTIES TIMEOUT 240)
# the kriged map's algebra (white box): the kernel's closed forms against dense LAPACK, the
# likelihood in the points' and the cells' space against each other and central differences
# the adaptive scan's greedy batch against closed forms and the information-form posterior
ipsd_add_test(test_adapt ipsfit)
# the adaptive scan's planner: travel order against every permutation, the lattice by hand, a
# half-seen tilted pixel of box integrals, the stop rule, a whole scan of it to a target (~3 s)
ipsd_add_test(test_adapt_plan ipsfit)
set_tests_properties(test_adapt_plan PROPERTIES TIMEOUT 120)
ipsd_add_test(test_krige_lik ipsfit)
target_include_directories(test_krige_lik PRIVATE ${PROJECT_SOURCE_DIR}/fit)
