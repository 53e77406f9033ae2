// Umbrella header of citylod::geo.
#pragma once

#include "citylod/geo/crs.hpp"
#include "citylod/geo/georef.hpp"
#include "citylod/geo/local_frame.hpp"
#include "citylod/geo/transformer.hpp"
#include "citylod/geo/types.hpp"
#include "citylod/geo/units.hpp"
#include "citylod/geo/vertical.hpp"
