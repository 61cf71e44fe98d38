// Private to rti/: what the relight web format (OpenLIME, relight-cli) orders differently from vdrig.
#pragma once

namespace vdrig::rti {

/// Relight's PTM term k is vdrig's PTM coefficient kRelightPtmOrder[k]: relight (OpenLIME's PTM.lightWeights,
/// relight's Rti::lightWeightsPtm) orders them 1, x, y, x^2, xy, y^2; vdrig and the .ptm file x^2, y^2, xy, x, y, 1.
inline constexpr int kRelightPtmOrder[6] = {5, 3, 4, 0, 2, 1};

}  // namespace vdrig::rti
