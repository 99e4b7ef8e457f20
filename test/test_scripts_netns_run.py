"""scripts/netns-run --shell: several processes in one private network, apart from every other
scripts/netns-run (docs/cli.md's way to replay a bag into a running node).
"""

import subprocess

from conftest import REPO

NETNS_RUN = str(REPO / 'scripts' / 'netns-run')
NS = 'readlink /proc/self/ns/net'


def test_processes_started_from_the_shell_share_one_private_network():
    script = f'{NS}\nsh -c "{NS}" &\nsh -c "{NS}" &\nwait\nip -o link show | wc -l\n'
    shell = subprocess.run(
        [NETNS_RUN, '--shell'], input=script, capture_output=True, text=True, timeout=30
    )
    assert shell.returncode == 0, shell.stderr
    *namespaces, links = shell.stdout.split()
    other = subprocess.run([NETNS_RUN, 'sh', '-c', NS], capture_output=True, text=True, timeout=30)
    own = subprocess.run(['sh', '-c', NS], capture_output=True, text=True, timeout=30)
    assert len(namespaces) == 3 and len(set(namespaces)) == 1  # the shell and its two children
    assert namespaces[0] not in (other.stdout.strip(), own.stdout.strip())
    assert links == '1'  # loopback only


def test_a_script_runs_as_bash_c_in_one_namespace():
    shell = subprocess.run(
        [NETNS_RUN, '--shell', '-c', f'{NS} & {NS}; wait'],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert shell.returncode == 0 and len(set(shell.stdout.split())) == 1, shell.stdout
