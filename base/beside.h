// Two independent pieces of work side by side: `side` on a new thread, `main` on the calling one. Both have
// finished when RunBeside returns, also when either throws; then the exception is rethrown on the calling
// thread (main's before side's). A bare std::thread would end the process instead: its destructor
// terminates while joinable (main threw before the join), and so does an exception leaving its function.
// Without a thread to be had, `side` runs after `main` on the calling thread.
#ifndef BISTABLE_BASE_BESIDE_H_
#define BISTABLE_BASE_BESIDE_H_

#include <exception>
#include <system_error>
#include <thread>

namespace bistable {

template <class Side, class Main>
void RunBeside(Side&& side, Main&& main) {
  std::exception_ptr side_error, main_error;
  std::thread t;
  try {
    t = std::thread([&] {
      try {
        side();
      } catch (...) {
        side_error = std::current_exception();
      }
    });
  } catch (const std::system_error&) {  // no thread: one after the other
    main();
    side();
    return;
  }
  try {
    main();
  } catch (...) {
    main_error = std::current_exception();
  }
  t.join();
  if (main_error) std::rethrow_exception(main_error);
  if (side_error) std::rethrow_exception(side_error);
}

}  // namespace bistable

#endif  // BISTABLE_BASE_BESIDE_H_
