// `farm_sim`: many simulated workers against one real server (or several servers of one farm on
// a shared store), to measure how many workers a server carries
// (docs/results/service-measurements.md, "How many workers one server carries", "Two servers on
// one PostgreSQL").
//
// Each simulated worker is a thread with its own gRPC channel (its own TCP connection, as a
// real worker process has) that follows the worker protocol of proto/render.proto: register,
// lease, "render" by sleeping the lease's iterations × --iteration-ms while heartbeating every
// heartbeat_seconds the server asked for, then report the range's sums. The sums are made up
// but valid and exactly known (iteration i gives pixel value k the value
// 1 + ((i + k) mod 8) / 8), so that the finished image says whether every iteration was merged
// exactly once: its mean over iterations 1..N is computable (tests/integration/test_farm_sim.py
// checks it).
//
// It submits its own jobs (a tiny scene uploaded as an asset), measures the latency of every
// Lease, Heartbeat and Report call, counts leases and reports, and samples the server's CPU
// time and memory from /proc/PID (--server-pid). Output: one JSON object (--json FILE, else
// stdout).
//
// --server A:P,B:P (several servers of one farm): simulated worker i registers with and leases
// from server i mod n, the jobs are submitted to the first; --server-pid P1,P2 sums the
// servers' CPU and memory; --database-pid lists the database's processes, whose CPU is counted
// apart (database_cpu_*).
//
//   farm_sim --server 127.0.0.1:PORT --workers 200 --seconds 30 --warmup 10 --server-pid PID
//   farm_sim --server 127.0.0.1:PORT --workers 4 --jobs 2 --iterations 300 --until-done
//
// With --jobs 0 the workers find nothing to do and poll as idle workers do (service/idle_poll.h:
// 0.3 s growing to 2 s, jittered).
// With --until-done the jobs have --iterations each and the run ends when every job is DONE
// (or after --seconds, a failure); every --duplicate-every'th report is then sent a second
// time, which the server must drop (merged=false).

#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "core/util/sha256.h"
#include "render.grpc.pb.h"
#include "service/idle_poll.h"

namespace {

namespace v1 = ::render::v1;
using Clock = std::chrono::steady_clock;

struct Options {
    std::vector<std::string> servers = {"127.0.0.1:50051"};
    std::string token;
    int workers = 50;
    double seconds = 30;
    double warmup = 5;
    double iteration_ms = 100;  // simulated render time of one iteration
    int width = 16, height = 16;
    int jobs = 1;
    uint64_t iterations = 0;  // per job; 0 = the largest the server accepts
    bool until_done = false;
    int duplicate_every = 0;  // with --until-done: resend every Nth report
    std::vector<int> server_pids;
    std::vector<int> database_pids;
    std::string json;
};

[[noreturn]] void usage(const std::string& error) {
    std::cerr << "farm_sim: " << error << "\n"
              << "usage: farm_sim --server HOST:PORT[,HOST:PORT...] [--workers N] [--seconds S]\n"
                 "                [--warmup S] [--iteration-ms MS] [--resolution WxH] [--jobs J]\n"
                 "                [--iterations N] [--until-done] [--duplicate-every K]\n"
                 "                [--server-pid PID[,PID...]] [--database-pid PID[,PID...]]\n"
                 "                [--token T] [--json FILE]\n";
    std::exit(2);
}

std::vector<std::string> split_commas(const std::string& list) {
    std::vector<std::string> out;
    std::stringstream in(list);
    for (std::string item; std::getline(in, item, ',');)
        if (!item.empty()) out.push_back(item);
    return out;
}

std::vector<int> pid_list(const std::string& list) {
    std::vector<int> out;
    for (const std::string& item : split_commas(list)) out.push_back(std::stoi(item));
    return out;
}

Options parse(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= argc) usage(a + " needs a value");
            return argv[++i];
        };
        try {
            if (a == "--server")
                o.servers = split_commas(value());
            else if (a == "--token")
                o.token = value();
            else if (a == "--workers")
                o.workers = std::stoi(value());
            else if (a == "--seconds")
                o.seconds = std::stod(value());
            else if (a == "--warmup")
                o.warmup = std::stod(value());
            else if (a == "--iteration-ms")
                o.iteration_ms = std::stod(value());
            else if (a == "--jobs")
                o.jobs = std::stoi(value());
            else if (a == "--iterations")
                o.iterations = std::stoull(value());
            else if (a == "--until-done")
                o.until_done = true;
            else if (a == "--duplicate-every")
                o.duplicate_every = std::stoi(value());
            else if (a == "--server-pid")
                o.server_pids = pid_list(value());
            else if (a == "--database-pid")
                o.database_pids = pid_list(value());
            else if (a == "--json")
                o.json = value();
            else if (a == "--resolution") {
                const std::string v = value();
                if (std::sscanf(v.c_str(), "%dx%d", &o.width, &o.height) != 2)
                    usage("--resolution must be WxH");
            } else
                usage("unknown option " + a);
        } catch (const std::logic_error&) {
            usage("bad value for " + a);
        }
    }
    if (o.workers < 1 || o.workers > 10000) usage("--workers must be in [1, 10000]");
    if (o.jobs < 0 || o.width < 1 || o.height < 1 || !(o.iteration_ms >= 0))
        usage("--resolution and --iteration-ms must be positive, --jobs at least 0");
    if (o.until_done && o.jobs < 1) usage("--until-done needs --jobs of at least 1");
    if (o.until_done && o.iterations == 0) usage("--until-done needs --iterations");
    if (o.servers.empty()) usage("--server needs an address");
    return o;
}

// A JSON number (null when not finite).
std::string number(double x) {
    if (!std::isfinite(x)) return "null";
    std::ostringstream s;
    s.precision(9);
    s << x;
    return s.str();
}

// The sums of a range, as the protocol defines them (sum, then odd_sum over odd iterations).
// Iteration i gives value k the value 1 + ((i + k) mod 8) / 8: exact in float64, and periodic
// in i with period 8 (parity included), so a range's sum costs at most 16 terms per value.
double value_of(uint64_t i, size_t k) {
    return 1.0 + double((i + k) % 8) / 8.0;
}

void range_sums(uint64_t first, uint64_t end, size_t n, std::vector<double>* sum,
                std::vector<double>* odd_sum) {
    sum->assign(n, 0.0);
    odd_sum->assign(n, 0.0);
    const uint64_t count = end - first, periods = count / 8;
    for (size_t k = 0; k < n; ++k) {
        double s = 0, odd = 0, period_s = 0, period_odd = 0;
        for (uint64_t i = first; i < first + 8; ++i) {
            period_s += value_of(i, k);
            if (i % 2 == 1) period_odd += value_of(i, k);
        }
        s = period_s * double(periods);
        odd = period_odd * double(periods);
        for (uint64_t i = first + periods * 8; i < end; ++i) {
            s += value_of(i, k);
            if (i % 2 == 1) odd += value_of(i, k);
        }
        (*sum)[k] = s;
        (*odd_sum)[k] = odd;
    }
}

// A minimal scene (the server loads it at submit): a diffuse sphere under a constant sky.
std::string scene_xml(int width, int height) {
    std::ostringstream s;
    s << R"(<scene version="3.0.0">
  <integrator type="path"/>
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0,0,-4" target="0,0,0" up="0,1,0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="1"/></sampler>
    <film type="hdrfilm"><integer name="width" value=")"
      << width << R"("/><integer name="height" value=")" << height << R"("/></film>
  </sensor>
  <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
  <shape type="sphere"><bsdf type="diffuse"/></shape>
</scene>
)";
    return s.str();
}

// Latencies of one kind of call, in seconds.
struct Latencies {
    std::mutex mu;
    std::vector<double> seconds;
    void add(double s) {
        std::lock_guard lock(mu);
        seconds.push_back(s);
    }
    double percentile(double p) {
        std::lock_guard lock(mu);
        if (seconds.empty()) return 0;
        std::vector<double> v = seconds;
        const size_t i = std::min(v.size() - 1, size_t(p * double(v.size())));
        std::nth_element(v.begin(), v.begin() + long(i), v.end());
        return v[i];
    }
    size_t count() {
        std::lock_guard lock(mu);
        return seconds.size();
    }
};

// CPU seconds (user + system) and resident memory of a process, from /proc.
struct ProcSample {
    double cpu_seconds = 0;
    double rss_mb = 0;
    double peak_rss_mb = 0;
};

ProcSample sample_process(int pid);

// The sum over processes (memory summed too: the servers' RSS together).
ProcSample sample_processes(const std::vector<int>& pids) {
    ProcSample out;
    for (int pid : pids) {
        const ProcSample one = sample_process(pid);
        out.cpu_seconds += one.cpu_seconds;
        out.rss_mb += one.rss_mb;
        out.peak_rss_mb += one.peak_rss_mb;
    }
    return out;
}

ProcSample sample_process(int pid) {
    ProcSample out;
    const std::string dir = pid > 0 ? "/proc/" + std::to_string(pid) : "/proc/self";
    std::ifstream stat(dir + "/stat");
    std::string line;
    if (std::getline(stat, line)) {
        // Fields after the command (which may contain spaces) start after the last ')':
        // state is field 3, utime 14, stime 15.
        std::istringstream rest(line.substr(line.rfind(')') + 2));
        std::vector<std::string> f;
        for (std::string x; rest >> x;) f.push_back(x);
        if (f.size() > 12)
            out.cpu_seconds = (std::stod(f[11]) + std::stod(f[12])) / double(sysconf(_SC_CLK_TCK));
    }
    std::ifstream status(dir + "/status");
    while (std::getline(status, line)) {
        if (line.rfind("VmRSS:", 0) == 0) out.rss_mb = std::stod(line.substr(6)) / 1024.0;
        if (line.rfind("VmHWM:", 0) == 0) out.peak_rss_mb = std::stod(line.substr(6)) / 1024.0;
    }
    return out;
}

class Farm {
  public:
    explicit Farm(Options o)
        : o_(std::move(o)),
          values_(size_t(o_.width) * o_.height * 3),
          leases_by_server_(o_.servers.size()) {}

    int run();

  private:
    std::shared_ptr<grpc::Channel> channel(int index) const {
        grpc::ChannelArguments args;
        // Its own connection, as a separate worker process has (gRPC shares subchannels of
        // equal channels otherwise).
        args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
        args.SetInt("farm_sim.worker", index);
        return grpc::CreateCustomChannel(o_.servers[server_of(index)],
                                         grpc::InsecureChannelCredentials(), args);
    }
    // Worker i's server; the submits and checks (negative indices) go to the first.
    size_t server_of(int index) const { return index < 0 ? 0 : size_t(index) % o_.servers.size(); }
    void prepare(grpc::ClientContext& c, double timeout = 60) const {
        if (!o_.token.empty()) c.AddMetadata("authorization", "Bearer " + o_.token);
        c.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::milliseconds(int64_t(timeout * 1000)));
    }
    bool submit_jobs();
    void worker(int index);
    // Sleeps until `until` or the stop; false when stopped.
    bool sleep_until(Clock::time_point until) {
        std::unique_lock lock(stop_mu_);
        return !stop_cv_.wait_until(lock, until, [&] { return stop_.load(); });
    }
    bool report(v1::WorkerService::Stub& stub, const v1::Lease& lease, double render_seconds,
                bool* merged);
    bool all_jobs_done();
    void fail(const std::string& what) {
        std::lock_guard lock(errors_mu_);
        if (errors_.size() < 20) errors_.push_back(what);
        ++error_count_;
    }
    std::string json(double window, const ProcSample& s0, const ProcSample& s1,
                     const ProcSample& self0, const ProcSample& self1, const ProcSample& db0,
                     const ProcSample& db1, double peak_rss);

    Options o_;
    size_t values_;
    std::vector<std::string> job_ids_;
    std::atomic<bool> stop_{false};
    std::atomic<bool> measuring_{false};
    std::mutex stop_mu_;
    std::condition_variable stop_cv_;
    Latencies lease_latency_, empty_lease_latency_, report_latency_, heartbeat_latency_;
    std::atomic<uint64_t> leases_{0}, leases_empty_{0}, reports_{0}, reports_merged_{0},
        heartbeats_{0}, cancelled_{0}, abandoned_{0};
    std::vector<std::atomic<uint64_t>> leases_by_server_;  // measured leases, per server
    // Over the whole run (--until-done checks): leases granted, first reports merged,
    // duplicate reports sent and those (wrongly) merged.
    std::atomic<uint64_t> total_leases_{0}, total_merged_{0}, total_not_merged_{0},
        duplicates_sent_{0}, duplicates_merged_{0};
    std::mutex ranges_mu_;
    std::map<std::pair<std::string, uint32_t>, std::vector<std::pair<uint64_t, uint64_t>>>
        ranges_;  // reported and merged, per (job, frame)
    std::mutex errors_mu_;
    std::vector<std::string> errors_;
    std::atomic<uint64_t> error_count_{0};
};

bool Farm::submit_jobs() {
    auto stub = v1::JobService::NewStub(channel(-1));
    const std::string scene = scene_xml(o_.width, o_.height);
    render::Sha256 hash;
    hash.update(scene);
    const std::string sha = hash.hex_digest();
    {
        v1::BundleFile uploaded;
        grpc::ClientContext c;
        prepare(c);
        auto writer = stub->UploadAsset(&c, &uploaded);
        v1::AssetChunk chunk;
        chunk.set_sha256(sha);
        chunk.set_size(scene.size());
        chunk.set_data(scene);
        writer->Write(chunk);
        writer->WritesDone();
        if (grpc::Status st = writer->Finish(); !st.ok()) {
            std::cerr << "farm_sim: upload failed: " << st.error_message() << "\n";
            return false;
        }
    }
    for (int j = 0; j < o_.jobs; ++j) {
        v1::SubmitJobRequest request;
        request.set_name("farm_sim-" + std::to_string(j));
        request.mutable_bundle()->set_scene_path("scene.xml");
        v1::BundleFile* f = request.mutable_bundle()->add_files();
        f->set_path("scene.xml");
        f->set_sha256(sha);
        f->set_size(scene.size());
        v1::RenderSettings* s = request.mutable_settings();
        s->set_algorithm("pt");
        s->set_iterations(o_.iterations ? o_.iterations : 10000000);
        s->set_width(uint32_t(o_.width));
        s->set_height(uint32_t(o_.height));
        v1::Job job;
        grpc::ClientContext c;
        prepare(c);
        if (grpc::Status st = stub->SubmitJob(&c, request, &job); !st.ok()) {
            std::cerr << "farm_sim: submit failed: " << st.error_message() << "\n";
            return false;
        }
        job_ids_.push_back(job.id());
    }
    return true;
}

bool Farm::report(v1::WorkerService::Stub& stub, const v1::Lease& lease, double render_seconds,
                  bool* merged) {
    const uint64_t first = lease.first_iteration(), end = lease.end_iteration();
    const uint64_t count = end - first;
    std::vector<double> sum, odd_sum;
    range_sums(first, end, values_, &sum, &odd_sum);
    grpc::ClientContext c;
    prepare(c);
    v1::ReportReply reply;
    const auto start = Clock::now();
    auto writer = stub.Report(&c, &reply);
    v1::ReportChunk chunk;
    v1::ReportHeader* h = chunk.mutable_header();
    h->set_lease_id(lease.lease_id());
    h->set_count(count);
    h->set_odd_count(end / 2 - first / 2);
    h->set_width(uint32_t(o_.width));
    h->set_height(uint32_t(o_.height));
    h->set_samples(count * values_ / 3);
    h->set_rays(2 * count * values_ / 3);
    h->set_render_seconds(render_seconds);
    // As the real worker does, a one-iteration report leaves odd_sum out.
    h->set_odd_sum_omitted(count == 1);
    writer->Write(chunk);
    std::string bytes(reinterpret_cast<const char*>(sum.data()), sum.size() * sizeof(double));
    if (count != 1)
        bytes.append(reinterpret_cast<const char*>(odd_sum.data()),
                     odd_sum.size() * sizeof(double));
    constexpr size_t kChunk = size_t(1) << 20;
    for (size_t at = 0; at < bytes.size(); at += kChunk) {
        v1::ReportChunk values;
        values.set_values(bytes.substr(at, kChunk));
        if (!writer->Write(values)) break;
    }
    writer->WritesDone();
    const grpc::Status st = writer->Finish();
    if (measuring_)
        report_latency_.add(std::chrono::duration<double>(Clock::now() - start).count());
    if (!st.ok()) {
        fail("report " + lease.lease_id() + ": " + st.error_message());
        return false;
    }
    *merged = reply.merged();
    return true;
}

void Farm::worker(int index) {
    auto stub = v1::WorkerService::NewStub(channel(index));
    std::string worker_id;
    double heartbeat_seconds = 2;
    while (!stop_ && worker_id.empty()) {
        v1::RegisterWorkerRequest request;
        request.set_host("farm-sim-" + std::to_string(index));
        request.set_threads(1);
        request.set_version("farm_sim");
        v1::RegisterWorkerReply reply;
        grpc::ClientContext c;
        prepare(c);
        if (grpc::Status st = stub->RegisterWorker(&c, request, &reply); !st.ok()) {
            fail("register: " + st.error_message());
            sleep_until(Clock::now() + std::chrono::seconds(1));
            continue;
        }
        worker_id = reply.worker_id();
        if (reply.heartbeat_seconds() > 0) heartbeat_seconds = reply.heartbeat_seconds();
    }
    uint64_t reports_sent = 0;
    render::service::IdlePoll idle(uint64_t(index) * 0x9e3779b97f4a7c15ull + 1);
    while (!stop_) {
        v1::LeaseRequest request;
        request.set_worker_id(worker_id);
        v1::LeaseReply reply;
        grpc::ClientContext c;
        prepare(c);
        const auto start = Clock::now();
        const grpc::Status st = stub->Lease(&c, request, &reply);
        const double latency = std::chrono::duration<double>(Clock::now() - start).count();
        if (!st.ok()) {
            fail("lease: " + st.error_message());
            sleep_until(Clock::now() + std::chrono::milliseconds(300));
            continue;
        }
        if (!reply.granted()) {
            if (measuring_) {
                empty_lease_latency_.add(latency);
                ++leases_empty_;
            }
            // As the worker naps (the same schedule).
            sleep_until(Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                           std::chrono::duration<double>(idle.next())));
            continue;
        }
        idle.reset();
        ++total_leases_;
        if (measuring_) {
            lease_latency_.add(latency);
            ++leases_;
            ++leases_by_server_[server_of(index)];
        }
        const v1::Lease& lease = reply.lease();
        // "Render": the lease's iterations take iteration_ms each; heartbeat meanwhile.
        const uint64_t count = lease.end_iteration() - lease.first_iteration();
        const double render_seconds = double(count) * o_.iteration_ms / 1000.0;
        const auto render_start = Clock::now();
        const auto render_end = render_start + std::chrono::duration_cast<Clock::duration>(
                                                   std::chrono::duration<double>(render_seconds));
        bool alive = true;
        auto next_heartbeat = render_start + std::chrono::duration_cast<Clock::duration>(
                                                 std::chrono::duration<double>(heartbeat_seconds));
        while (alive && next_heartbeat < render_end) {
            if (!sleep_until(next_heartbeat)) break;
            v1::HeartbeatRequest hb;
            hb.set_worker_id(worker_id);
            hb.add_lease_ids(lease.lease_id());
            hb.mutable_rates()->set_iterations_per_second(
                o_.iteration_ms > 0 ? 1000.0 / o_.iteration_ms : 0);
            v1::HeartbeatReply hb_reply;
            grpc::ClientContext hc;
            prepare(hc);
            const auto hb_start = Clock::now();
            const grpc::Status hs = stub->Heartbeat(&hc, hb, &hb_reply);
            if (measuring_) {
                heartbeat_latency_.add(
                    std::chrono::duration<double>(Clock::now() - hb_start).count());
                ++heartbeats_;
            }
            if (!hs.ok()) fail("heartbeat: " + hs.error_message());
            for (const std::string& id : hb_reply.cancelled_lease_ids())
                if (id == lease.lease_id()) alive = false;
            next_heartbeat += std::chrono::duration_cast<Clock::duration>(
                std::chrono::duration<double>(heartbeat_seconds));
        }
        if (!alive) {
            ++cancelled_;
            continue;
        }
        if (!sleep_until(render_end)) {
            ++abandoned_;  // stopped mid-lease: the real worker's second signal
            break;
        }
        bool merged = false;
        if (!report(*stub, lease, render_seconds, &merged)) continue;
        ++reports_sent;
        if (measuring_) {
            ++reports_;
            if (merged) ++reports_merged_;
        }
        if (merged) {
            ++total_merged_;
            std::lock_guard lock(ranges_mu_);
            ranges_[{lease.job_id(), lease.frame()}].push_back(
                {lease.first_iteration(), lease.end_iteration()});
        } else {
            ++total_not_merged_;
        }
        if (o_.duplicate_every > 0 && reports_sent % uint64_t(o_.duplicate_every) == 0) {
            // A worker that did not hear the reply sends the same report again: the server
            // must drop it.
            bool again = false;
            if (report(*stub, lease, render_seconds, &again)) {
                ++duplicates_sent_;
                if (again) ++duplicates_merged_;
            }
        }
    }
}

bool Farm::all_jobs_done() {
    auto stub = v1::JobService::NewStub(channel(-2));
    for (const std::string& id : job_ids_) {
        v1::GetJobRequest request;
        request.set_job_id(id);
        v1::Job job;
        grpc::ClientContext c;
        prepare(c);
        if (!stub->GetJob(&c, request, &job).ok()) return false;
        if (job.state() != v1::JOB_STATE_DONE) return false;
    }
    return true;
}

std::string Farm::json(double window, const ProcSample& s0, const ProcSample& s1,
                       const ProcSample& self0, const ProcSample& self1, const ProcSample& db0,
                       const ProcSample& db1, double peak_rss) {
    std::ostringstream j;
    auto rate = [&](uint64_t n) { return number(window > 0 ? double(n) / window : 0); };
    const bool measured = !o_.server_pids.empty();
    j << "{\n";
    j << "  \"workers\": " << o_.workers << ",\n";
    j << "  \"servers\": " << o_.servers.size() << ", \"leases_by_server\": [";
    for (size_t i = 0; i < leases_by_server_.size(); ++i)
        j << (i ? ", " : "") << leases_by_server_[i].load();
    j << "],\n";
    j << "  \"iteration_ms\": " << number(o_.iteration_ms) << ",\n";
    j << "  \"width\": " << o_.width << ", \"height\": " << o_.height << ",\n";
    j << "  \"window_seconds\": " << number(window) << ",\n";
    j << "  \"leases\": " << leases_ << ", \"leases_per_second\": " << rate(leases_) << ",\n";
    j << "  \"empty_leases_per_second\": " << rate(leases_empty_) << ",\n";
    j << "  \"reports\": " << reports_ << ", \"reports_per_second\": " << rate(reports_) << ",\n";
    j << "  \"reports_merged\": " << reports_merged_ << ",\n";
    j << "  \"heartbeats_per_second\": " << rate(heartbeats_) << ",\n";
    auto lat = [&](const char* name, Latencies& l) {
        j << "  \"" << name << "_ms\": {\"count\": " << l.count()
          << ", \"p50\": " << number(l.percentile(0.5) * 1e3)
          << ", \"p99\": " << number(l.percentile(0.99) * 1e3)
          << ", \"max\": " << number(l.percentile(1.0) * 1e3) << "},\n";
    };
    lat("lease", lease_latency_);
    lat("empty_lease", empty_lease_latency_);
    lat("report", report_latency_);
    lat("heartbeat", heartbeat_latency_);
    j << "  \"server_cpu_percent\": "
      << number(window > 0 && measured ? 100 * (s1.cpu_seconds - s0.cpu_seconds) / window : 0)
      << ",\n";
    // Server CPU per lease cycle (Lease + Heartbeats + Report): what one worker costs the
    // server per lease, less sensitive to the machine's other load than the rates.
    j << "  \"server_cpu_ms_per_lease\": "
      << number(leases_ + leases_empty_ > 0 && measured
                    ? 1e3 * (s1.cpu_seconds - s0.cpu_seconds) / double(leases_ + leases_empty_)
                    : 0)
      << ",\n";
    // The database's processes (a shared store), counted apart from the servers.
    const bool db = !o_.database_pids.empty();
    j << "  \"database_cpu_percent\": "
      << number(window > 0 && db ? 100 * (db1.cpu_seconds - db0.cpu_seconds) / window : 0)
      << ", \"database_cpu_ms_per_lease\": "
      << number(leases_ + leases_empty_ > 0 && db
                    ? 1e3 * (db1.cpu_seconds - db0.cpu_seconds) / double(leases_ + leases_empty_)
                    : 0)
      << ",\n";
    j << "  \"server_rss_mb\": " << number(s1.rss_mb)
      << ", \"server_rss_peak_sampled_mb\": " << number(peak_rss)
      << ", \"server_vmhwm_mb\": " << number(s1.peak_rss_mb) << ",\n";
    j << "  \"driver_cpu_percent\": "
      << number(window > 0 ? 100 * (self1.cpu_seconds - self0.cpu_seconds) / window : 0) << ",\n";
    j << "  \"total_leases\": " << total_leases_ << ", \"total_merged\": " << total_merged_
      << ", \"total_not_merged\": " << total_not_merged_ << ",\n";
    j << "  \"duplicates_sent\": " << duplicates_sent_
      << ", \"duplicates_merged\": " << duplicates_merged_ << ",\n";
    j << "  \"cancelled\": " << cancelled_ << ", \"abandoned\": " << abandoned_ << ",\n";
    // Merged ranges per frame, sorted: the test checks they tile [1, iterations] exactly.
    j << "  \"merged_ranges\": {";
    bool first_frame = true;
    for (auto& [key, ranges] : ranges_) {
        std::sort(ranges.begin(), ranges.end());
        j << (first_frame ? "" : ",") << "\n    \"" << key.first << "/" << key.second << "\": [";
        for (size_t i = 0; i < ranges.size(); ++i)
            j << (i ? "," : "") << "[" << ranges[i].first << "," << ranges[i].second << "]";
        j << "]";
        first_frame = false;
    }
    j << "},\n";
    j << "  \"jobs\": [";
    for (size_t i = 0; i < job_ids_.size(); ++i)
        j << (i ? ", " : "") << "\"" << job_ids_[i] << "\"";
    j << "],\n";
    j << "  \"errors\": " << error_count_ << ", \"first_errors\": [";
    for (size_t i = 0; i < errors_.size(); ++i) {
        std::string e = errors_[i];
        for (char& ch : e)
            if (ch == '"' || ch == '\\' || ch < 32) ch = '\'';
        j << (i ? ", " : "") << "\"" << e << "\"";
    }
    j << "]\n}\n";
    return j.str();
}

int Farm::run() {
    if (!submit_jobs()) return 1;
    std::vector<std::thread> threads;
    threads.reserve(size_t(o_.workers));
    for (int i = 0; i < o_.workers; ++i) threads.emplace_back([this, i] { worker(i); });
    const auto start = Clock::now();
    const auto deadline = start + std::chrono::duration_cast<Clock::duration>(
                                      std::chrono::duration<double>(o_.seconds));
    ProcSample s0, self0, db0;
    double peak_rss = 0;
    bool done = false;
    if (o_.until_done) {
        // Correctness run: everything is counted; ends when every job is DONE.
        measuring_ = true;
        s0 = sample_processes(o_.server_pids);
        db0 = sample_processes(o_.database_pids);
        self0 = sample_process(0);
        while (Clock::now() < deadline && !(done = all_jobs_done()))
            std::this_thread::sleep_for(std::chrono::milliseconds(200));
    } else {
        std::this_thread::sleep_until(start + std::chrono::duration_cast<Clock::duration>(
                                                  std::chrono::duration<double>(o_.warmup)));
        measuring_ = true;
        s0 = sample_processes(o_.server_pids);
        db0 = sample_processes(o_.database_pids);
        self0 = sample_process(0);
        while (Clock::now() < deadline) {
            std::this_thread::sleep_for(std::chrono::milliseconds(500));
            peak_rss = std::max(peak_rss, sample_processes(o_.server_pids).rss_mb);
        }
    }
    const ProcSample s1 = sample_processes(o_.server_pids), self1 = sample_process(0),
                     db1 = sample_processes(o_.database_pids);
    const double window = std::chrono::duration<double>(Clock::now() - start).count() -
                          (o_.until_done ? 0 : o_.warmup);
    measuring_ = false;
    {
        std::lock_guard lock(stop_mu_);
        stop_ = true;
    }
    stop_cv_.notify_all();
    for (std::thread& t : threads) t.join();
    peak_rss = std::max(peak_rss, s1.rss_mb);
    const std::string out = json(window, s0, s1, self0, self1, db0, db1, peak_rss);
    if (o_.json.empty()) {
        std::cout << out;
    } else {
        std::ofstream f(o_.json);
        f << out;
    }
    if (o_.until_done && !done) {
        std::cerr << "farm_sim: the jobs were not DONE after " << o_.seconds << " s\n";
        return 1;
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    Farm farm(parse(argc, argv));
    return farm.run();
}
