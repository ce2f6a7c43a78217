# Jitter photometry (fit/jitter.h): analytic limits, the box integral, and a Monte Carlo on the
# simulated bench (instrument/sim.h), hence ipsinstr.
ipsd_add_test(test_jitter ipsinstr ipsfit)
set_tests_properties(test_jitter PROPERTIES TIMEOUT 120) # busy, optimised: a few s; ASan ~4x
