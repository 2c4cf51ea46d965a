// The opacity reset on the resident model, the twin of gs-train's `reset_opacity`: an opacity
// above `rule.reset_level` takes the logit `rule.reset_logit`, and every Gaussian's opacity
// moments start again at zero.

@compute @workgroup_size(256)
fn densify_reset(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    if (sigmoid(params[i].opacity_logit) > rule.reset_level) {
        params[i].opacity_logit = rule.reset_logit;
    }
    m_params[i].opacity_logit = 0.0;
    v_params[i].opacity_logit = 0.0;
}
