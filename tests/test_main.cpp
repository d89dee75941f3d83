// The doctest main of nexdyn_tests: every tests/**/test_*.cpp registers its cases with it.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>
