// marie-demo's report: the components' parameters as they read them, the map drawn with the
// trajectories (PNG), and the summary (summary.json and the last lines).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tools/demo/demo.h"

extern "C" {
#include "core/config.h"
#include "core/expand.h"
}

namespace marie_demo {

// The parameters of a component of the system file in a profile, as the component reads them:
// with the environment's ${...} expanded (the localizer's map names MARIE_MAP).
std::map<std::string, std::string> Demo::component_params(const char *profile, const char *component)
{
    marie_errors_t e = {};
    std::map<std::string, std::string> out;
    marie_system_t *sys = marie_system_load(opt_.system.c_str(), profile, &e);
    const marie_component_cfg_t *c = sys ? marie_system_component(sys, component) : nullptr;
    for (size_t i = 0; c && c->params && i < c->params->n; i++) {
        const marie_node_t *p = c->params->items[i];
        char why[256] = "";
        char *expanded = p->value ? marie_expand_env(p->value, why, sizeof why) : nullptr;
        if (expanded)
            out[p->key] = expanded;
        free(expanded);
    }
    marie_errors_print(&e, stderr);
    marie_errors_clear(&e);
    marie_system_destroy(sys);
    return out;
}

occmap_t *load_occmap(const std::string &yaml)
{
    marie_errors_t e = {};
    occmap_t *m = occmap_load(yaml.c_str(), &e);
    marie_errors_print(&e, stderr);
    marie_errors_clear(&e);
    return m;
}

double rms_of(const std::vector<double> &v, double *max)
{
    double sum = 0, mx = 0;
    for (double e : v) {
        sum += e * e;
        mx = std::max(mx, e);
    }
    if (max)
        *max = mx;
    return v.empty() ? NAN : std::sqrt(sum / v.size());
}

void Demo::draw_map(const occmap_t *m)
{
    // Image row 0 is the map's top row; free white, walls black, unknown grey.
    map_.create(m->height, m->width, CV_8UC1);
    for (int cy = 0; cy < m->height; cy++)
        for (int cx = 0; cx < m->width; cx++) {
            int8_t v = occmap_get(m, cx, cy);
            map_.at<uint8_t>(m->height - 1 - cy, cx) = v == OCCMAP_FREE ? 255 : v == OCCMAP_OCCUPIED ? 0 : 205;
        }
    res_ = m->resolution;
    ox_ = m->origin_x;
    oy_ = m->origin_y;
}

void Demo::write_png(const std::string &path)
{
    if (map_.empty())
        return;
    const int scale = 2;
    cv::Mat img;
    cv::cvtColor(map_, img, cv::COLOR_GRAY2BGR);
    cv::resize(img, img, cv::Size(), scale, scale, cv::INTER_NEAREST);
    auto px = [&](double x, double y) {
        return cv::Point(int((x - ox_) / res_ * scale), int(map_.rows * scale - (y - oy_) / res_ * scale));
    };
    auto draw = [&](const std::vector<Sample> &s, cv::Scalar colour, int width) {
        for (size_t i = 1; i < s.size(); i++)
            cv::line(img, px(s[i - 1].x, s[i - 1].y), px(s[i].x, s[i].y), colour, width, cv::LINE_AA);
    };
    draw(truth_, cv::Scalar(60, 170, 60), 4);
    draw(estimate_, cv::Scalar(40, 40, 220), 2);
    int k = 1;
    for (int id : goal_order_) {
        cv::Point p = px(goals_[id].x, goals_[id].y);
        cv::circle(img, p, 14, cv::Scalar(200, 90, 20), 3, cv::LINE_AA);
        cv::putText(img, std::to_string(k++), p + cv::Point(16, -10), cv::FONT_HERSHEY_SIMPLEX, 0.8,
                    cv::Scalar(200, 90, 20), 2, cv::LINE_AA);
    }
    if (!truth_.empty())
        cv::drawMarker(img, px(truth_.front().x, truth_.front().y), cv::Scalar(0, 0, 0), cv::MARKER_STAR, 24, 2);
    cv::rectangle(img, cv::Point(10, 8), cv::Point(880, 48), cv::Scalar(255, 255, 255), cv::FILLED);
    cv::putText(img, exploring_ ? "green: ground truth   red: mapper's estimate   blue: frontiers"
                                : "green: ground truth   red: localizer estimate   blue: goals",
                cv::Point(20, 36),
                cv::FONT_HERSHEY_SIMPLEX, 0.9, cv::Scalar(0, 0, 0), 2, cv::LINE_AA);
    cv::imwrite(path, img);
}

void Demo::summary(double wall_s)
{
    double mx;
    double rms = rms_of(errors_, &mx);
    int restarts = this->restarts();
    FILE *f = fopen((opt_.out + "/summary.json").c_str(), "w");
    if (f) {
        fprintf(f,
                "{\"goals\": %d, \"reached\": %d, \"missed\": %d, \"mission_done\": %s, \"rms\": %.4f, "
                "\"max\": %.4f, \"pose_samples\": %zu, \"restarts\": %d, \"kills\": %d, \"collisions\": %lld, "
                "\"estop_stop_s\": %.3f, \"wall_s\": %.1f, \"sim_s\": %.1f, \"system_cpu_percent\": %.1f, "
                "\"system_rss_mb\": %.1f, \"seed\": %llu%s}\n",
                ngoals_, reached_, missed_, mission_done_ ? "true" : "false", std::isnan(rms) ? -1.0 : rms, mx,
                errors_.size(), restarts, kills_, (long long)collisions_, estop_stop_s_, wall_s, sim_now_ / 1e6,
                cpu_samples_ ? cpu_sum_ / cpu_samples_ : -1.0, rss_peak_mb_, (unsigned long long)chaos_.seed,
                explore_json_.c_str());
        fclose(f);
    }
    printf("demo: whole system (components and managers): CPU %.0f%% of a core on average, RSS %.0f MB at most\n",
           cpu_samples_ ? cpu_sum_ / cpu_samples_ : -1.0, rss_peak_mb_);
    printf("demo: %d/%d goals reached, localization RMS %.2f m (max %.2f m), restarts %d, %.0f s\n", reached_,
           ngoals_, rms, mx, restarts, wall_s);
}

}  // namespace marie_demo
