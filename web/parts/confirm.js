// Asking before what cannot be undone: the button gives its place to the question, with Yes and Cancel (not the
// browser's dialog, which stops the page's live views while it is open). Resolves with the answer.
export function confirmFirst(button, question, yes) {
  return new Promise(resolve => {
    const box = document.createElement('span');
    box.className = 'confirm';
    box.setAttribute('role', 'group');
    box.innerHTML = '<span class="question"></span><button type="button" class="yes"></button>' +
      '<button type="button" class="cancel">Cancel</button>';
    box.firstChild.textContent = question;
    box.querySelector('.yes').textContent = yes;
    const answer = agreed => {
      box.remove();
      button.hidden = false;
      if (!agreed) button.focus();
      resolve(agreed);
    };
    box.querySelector('.yes').addEventListener('click', () => answer(true));
    box.querySelector('.cancel').addEventListener('click', () => answer(false));
    button.hidden = true;
    button.after(box);
    box.querySelector('.cancel').focus();  // Enter or Space right after the click must not say yes
  });
}
