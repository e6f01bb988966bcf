hs_add_gtest(test_bonded_validation LABEL validation SOURCES test_validation.cpp LIBS hs_bonded)
