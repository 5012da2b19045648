// A real single-node Slurm for a test: munged with a generated key, slurmctld
// and slurmd with a generated slurm.conf (free ports, state and spool in the
// test's folder, proctrack/pgid, task/none, no accounting), all as root and
// without systemd or cgroups. SLURM_CONF is set for this process, so sbatch /
// squeue / scancel run by locaid-sweep and by the test reach this cluster.
// The destructor cancels every job, then stops each daemon by its PID.
#pragma once

#include "free_port.hpp"
#include "pipeline/cli_support.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

namespace locaid::sweep_test {

class SlurmCluster {
 public:
  // `dir`'s parents must be traversable by everyone (munged checks its socket's folders).
  explicit SlurmCluster(const std::filesystem::path& dir) : dir_(dir) {
    namespace fs = std::filesystem;
    fs::create_directories(dir_);
    fs::permissions(dir_, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                              fs::perms::others_read | fs::perms::others_exec);
    for (const char* d : {"munge", "sock", "state", "spool", "log"}) fs::create_directories(dir_ / d);
    fs::permissions(dir_ / "munge", fs::perms::owner_all);
    fs::permissions(dir_ / "sock", fs::perms::owner_all | fs::perms::group_exec | fs::perms::others_exec |
                                       fs::perms::group_read | fs::perms::others_read);
    const std::string socket = (dir_ / "sock/munge.sock").string();
    if (!Run("mungekey -c -k " + (dir_ / "munge/munge.key").string()) ||
        !Run("munged --socket=" + socket + " --key-file=" + (dir_ / "munge/munge.key").string() +
             " --pid-file=" + (dir_ / "munge/munged.pid").string() + " --log-file=" +
             (dir_ / "log/munged.log").string() + " --seed-file=" + (dir_ / "munge/munged.seed").string()))
      return;
    pid_files_.push_back(dir_ / "munge/munged.pid");
    WriteConf(socket);
    ::setenv("SLURM_CONF", (dir_ / "slurm.conf").c_str(), 1);
    if (!Run("slurmctld -c -f " + (dir_ / "slurm.conf").string())) return;
    pid_files_.push_back(dir_ / "slurmctld.pid");
    if (!Run("slurmd -f " + (dir_ / "slurm.conf").string())) return;
    pid_files_.push_back(dir_ / "slurmd.pid");
    // Up once the node is idle (a few seconds).
    for (int i = 0; i < 150 && !ready_; ++i) {
      const auto r = test::RunCommand("sinfo -h -o %T");
      ready_ = r.exit_code == 0 && r.out.find("idle") != std::string::npos;
      if (!ready_) std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    if (!ready_) error_ = "the node never became idle: " + test::RunCommand("sinfo; tail -5 " +
                                                                            (dir_ / "log/slurmd.log").string()).out;
  }

  ~SlurmCluster() {
    test::RunCommand("scancel --full --quiet --user=root");  // jobs of this cluster only (SLURM_CONF)
    for (int i = 0; i < 100 && !test::RunCommand("squeue -h").out.empty(); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    for (auto it = pid_files_.rbegin(); it != pid_files_.rend(); ++it) Stop(*it);
    ::unsetenv("SLURM_CONF");
  }
  SlurmCluster(const SlurmCluster&) = delete;
  SlurmCluster& operator=(const SlurmCluster&) = delete;

  bool ready() const { return ready_; }
  const std::string& error() const { return error_; }

 private:
  bool Run(const std::string& cmd) {
    const auto r = test::RunCommand(cmd);
    if (r.exit_code != 0) error_ = cmd + ": " + r.out;
    return r.exit_code == 0;
  }


  void WriteConf(const std::string& munge_socket) {
    char host[256] = {};
    ::gethostname(host, sizeof host - 1);
    long mem_mb = 1024;
    std::ifstream meminfo("/proc/meminfo");
    std::string key;
    long kb = 0;
    if (meminfo >> key >> kb && key == "MemTotal:") mem_mb = std::max(512L, kb / 1024 - 1024);
    const int ctld_port = test_support::FreeLoopbackPort();
    int d_port = test_support::FreeLoopbackPort();
    while (d_port == ctld_port) d_port = test_support::FreeLoopbackPort();
    const std::string d = dir_.string();
    std::ofstream(dir_ / "slurm.conf")
        << "ClusterName=locaidtest\nSlurmctldHost=" << host << "(127.0.0.1)\n"
        << "SlurmctldPort=" << ctld_port << "\nSlurmdPort=" << d_port << "\n"
        << "SlurmUser=root\nSlurmdUser=root\nAuthType=auth/munge\nCredType=cred/munge\n"
        << "AuthInfo=socket=" << munge_socket << "\n"
        << "StateSaveLocation=" << d << "/state\nSlurmdSpoolDir=" << d << "/spool\n"
        << "SlurmctldPidFile=" << d << "/slurmctld.pid\nSlurmdPidFile=" << d << "/slurmd.pid\n"
        << "SlurmctldLogFile=" << d << "/log/slurmctld.log\nSlurmdLogFile=" << d << "/log/slurmd.log\n"
        << "ProctrackType=proctrack/pgid\nTaskPlugin=task/none\nJobAcctGatherType=jobacct_gather/none\n"
        << "AccountingStorageType=accounting_storage/none\nJobCompType=jobcomp/none\nMpiDefault=none\n"
        << "SwitchType=switch/none\nSelectType=select/cons_tres\nSelectTypeParameters=CR_Core\n"
        << "ReturnToService=2\nKillWait=5\n"
        << "NodeName=" << host << " NodeAddr=127.0.0.1 CPUs=2 RealMemory=" << mem_mb << " State=UNKNOWN\n"
        << "PartitionName=debug Nodes=" << host << " Default=YES MaxTime=INFINITE State=UP\n";
  }

  // SIGTERM, then SIGKILL after 10 s; waits until the process is gone.
  static void Stop(const std::filesystem::path& pid_file) {
    std::ifstream in(pid_file);
    pid_t pid = 0;
    if (!(in >> pid) || pid <= 1) return;
    ::kill(pid, SIGTERM);
    for (int i = 0; i < 200 && ::kill(pid, 0) == 0; ++i) {
      if (i == 100) ::kill(pid, SIGKILL);
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }

  std::filesystem::path dir_;
  std::vector<std::filesystem::path> pid_files_;
  bool ready_ = false;
  std::string error_;
};

}  // namespace locaid::sweep_test
